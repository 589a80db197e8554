"""bench contact-schur: every candidate builds SuperLU's Schur complement (to round-off), the study writes its table."""
import importlib.util

import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.benchmarks.contact.schur_candidates import CANDIDATES, REFERENCES, installed_candidates
from admmkit.benchmarks.contact.schur_study import run_study
from admmkit.problems.contact import assemble, example1, example2
from admmkit.problems.contact.solvers.schur import BoundarySchur


@pytest.fixture(scope="module", params=["ex1", "ex2"])
def ops(request):
    return assemble({"ex1": example1, "ex2": example2}[request.param](h=1 / 10))


@pytest.mark.parametrize("name", list(CANDIDATES))
def test_each_candidate_gives_todays_S(ops, name):
    fn, module = CANDIDATES[name]
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not installed")
    K = sp.csc_matrix(ops.K)
    today = BoundarySchur(K, ops.B, backend="superlu")
    contact = today.contact_dofs
    inner = np.setdiff1d(np.arange(K.shape[0]), contact)
    # block 8 and no extrapolation: every column computed, in several blocks
    res = fn(K, ops.B, inner, contact, 8, None) if "block" in name else fn(K, ops.B, inner, contact)
    assert res["setup"] == pytest.approx(sum(res["steps"].values()))
    assert not res["extrapolated"]
    if res["S"] is None:
        assert name.startswith("qdldl")
        return
    assert res["S"].shape == today.S.shape
    assert np.abs(res["S"] - today.S).max() <= 1e-12 * np.abs(today.S).max()


@pytest.mark.parametrize("name", ["superlu, contact last", "ldl, contact last"])
def test_contact_last_candidates_order_by_nested_dissection_given_coordinates(ops, name):
    fn = CANDIDATES[name][0]
    K = sp.csc_matrix(ops.K)
    plain = BoundarySchur(K, ops.B, backend="superlu")
    inner = np.setdiff1d(np.arange(K.shape[0]), plain.contact_dofs)
    res = fn(K, ops.B, inner, plain.contact_dofs, coordinates=ops.dof_coordinates())
    assert np.abs(res["S"] - plain.S).max() <= 1e-12 * np.abs(plain.S).max()
    assert set(res["steps"]) == {"ordering", "factorisation", "schur", "rest"}


def test_block_solves_extrapolate_from_the_first_blocks(ops):
    fn = CANDIDATES["superlu K_ii + block solves"][0]
    K = sp.csc_matrix(ops.K)
    contact = np.unique(sp.csr_matrix(ops.B).indices)
    inner = np.setdiff1d(np.arange(K.shape[0]), contact)
    res = fn(K, ops.B, inner, contact, 4, 1)
    assert res["extrapolated"] and res["S"].shape == (contact.size, 4)


def test_study_writes_the_ratio_and_the_candidates(tmp_path):
    out = tmp_path / "schur.md"
    names = ["superlu, contact last", "superlu K_ii + block solves", "qdldl factor of K (no S)"]
    rows = run_study(out=out, hs=(1 / 10,), examples=("ex1",), repeats=1, candidates=names, block=16, progress=False)
    (row,) = rows
    assert row["sadmm"]["total"] / row["ref"] > 0 and set(row["candidates"]) == set(names)
    assert row["candidates"]["superlu K_ii + block solves"]["error"] <= 1e-12
    text = out.read_text()
    assert "SADMM / (factorisation + solve)" in text and "qdldl factor of K (no S)" in text
    assert row["fastest"] in row["refs"] and row["ref"] == row["refs"]["superlu"]
    assert "ratio / fastest" in text and "Pip-only factorisation + solve of K" in text


@pytest.mark.parametrize("name", installed_candidates(REFERENCES))
def test_each_reference_solves_K(ops, name):
    K = sp.csc_matrix(ops.K)
    u = REFERENCES[name][0](K, ops.f, ops.dof_coordinates())
    assert np.linalg.norm(K @ u - ops.f) <= 1e-10 * np.linalg.norm(ops.f)


def test_unknown_candidate_is_refused():
    with pytest.raises(ValueError, match="candidates must be among"):
        run_study(hs=(1 / 10,), examples=("ex1",), repeats=1, candidates=["mumps"], progress=False)


def test_installed_candidates_always_include_scipys():
    assert "superlu, contact last" in installed_candidates()


def test_cli_writes_over_an_existing_file_and_refuses_a_folder(tmp_path, capsys):
    from admmkit.cli import main
    out = tmp_path / "schur.md"
    out.write_text("old")
    # the README's regeneration command names an existing file: it must run (it was refused as "not a folder")
    assert main(["bench", "contact-schur", "--h", "1/10", "--repeats", "1", "--out", str(out)]) == 0
    assert "SADMM / (factorisation + solve)" in out.read_text()
    assert main(["bench", "contact-schur", "--h", "1/10", "--repeats", "1", "--out", str(tmp_path)]) != 0
    assert "--out" in capsys.readouterr().err
