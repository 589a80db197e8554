"""``admmkit bench policies``: the rules on contact (frictionless and Tresca) and the obstacle across rho_0 (smoke run)."""
import pytest
import csv

from admmkit.benchmarks.policies.study import run


@pytest.mark.study
def test_policy_sweep_smoke(tmp_path):
    results = run(tmp_path, rules=("aadmm", "quantized"), quick=True, progress=False, max_iter=3000,
                  command="admmkit bench policies --quick")
    for name in ("README.md", "sweep.csv", "sweep.png", "sweep.svg"):
        assert (tmp_path / name).stat().st_size > 0, name
    with (tmp_path / "sweep.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 3 * 2 * 2 * 3               # cases (contact, obstacle, Tresca) x rules x orders x rho_0
    assert all(r["reached"] == "True" for r in rows)  # both rules reach the reference from every rho_0
    for case in results:
        facts = {rule: sum(int(r["factorizations"]) for r in rows if r["case"] == case and r["rule"] == rule)
                 for rule in ("aadmm", "quantized")}
        assert facts["quantized"] < facts["aadmm"], case  # the grid reuses factorisations
    assert "Iterations to a relative error of 1e-06" in (tmp_path / "README.md").read_text()
