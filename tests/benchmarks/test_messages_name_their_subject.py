"""Messages name their subject (#27 item 4): a corrupt MAT file is skipped by name; a full disk names the file."""
import errno
import os
import shutil
from pathlib import Path

import pytest

from admmkit.benchmarks.runner import sweep
from admmkit.io import write_text
from admmkit.problems.qp.mat import read_matrices

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"


def corrupt_folder(tmp_path):
    """A folder with one good MAT file (HS21 from the shared set) and one corrupt one."""
    folder = tmp_path / "mm"
    folder.mkdir()
    shutil.copy(SHARED / "HS21.mat", folder / "HS21.mat")
    (folder / "BROKEN.mat").write_bytes(b"MATLAB 5.0 MAT-file" + b"\x00" * 100 + b"AB" + os.urandom(200))
    return folder


def test_read_matrices_names_the_file(tmp_path):
    bad = tmp_path / "BROKEN.mat"
    bad.write_bytes(b"not a mat file at all")
    with pytest.raises(ValueError, match="BROKEN.mat"):
        read_matrices(bad)


@pytest.mark.study
@pytest.mark.skipif(not (SHARED / "HS21.mat").exists(), reason="needs ../shared/data/maros_meszaros")
def test_bench_qp_lists_a_corrupt_file_as_skipped_and_goes_on(tmp_path):
    from admmkit.benchmarks.qp.maros_meszaros import run_benchmark
    res = run_benchmark(corrupt_folder(tmp_path), tmp_path / "out", policy_names=["osqp"], orders=["xz"],
                        max_iter=200, variants=("preset",), osqp_direct=False, progress=False)
    assert "BROKEN" in res["skipped"] and "BROKEN.mat" in res["skipped"]["BROKEN"]
    assert {row["problem"] for row in res["rows"]} == {"HS21"}


@pytest.mark.skipif(not (SHARED / "HS21.mat").exists(), reason="needs ../shared/data/maros_meszaros")
def test_qp_fidelity_lists_a_corrupt_file_as_skipped(tmp_path):
    from admmkit.benchmarks.qp.qp_fidelity import select
    skipped = {}
    assert [name for name, _ in select(corrupt_folder(tmp_path), 1e9, None, skipped)] == ["HS21"]
    assert "BROKEN.mat" in skipped["BROKEN"]


def no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_full_disk_under_a_sweep_names_the_results_file(tmp_path, monkeypatch):
    monkeypatch.setattr(sweep.os, "write", no_space)
    path = tmp_path / "results.jsonl"
    with pytest.raises(OSError, match=f"could not write {path}: No space left on device") as info:
        sweep.append_result(path, {"id": "a"})
    assert info.value.errno == errno.ENOSPC


def test_a_full_disk_under_an_atomic_write_names_the_file(tmp_path, monkeypatch):
    import admmkit.io as io
    monkeypatch.setattr(io.os, "fsync", no_space)
    with pytest.raises(OSError, match=f"could not write {tmp_path / 'report.md'}"):
        write_text(tmp_path / "report.md", "text")
    assert list(tmp_path.iterdir()) == []            # nothing half-written is left
