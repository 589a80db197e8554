"""admmkit bench split-speed: the building blocks' time per iteration, compiled and in Python (a tiny run)."""
import csv

import pytest

pytest.importorskip("numba")
pytest.importorskip("qdldl")


def test_split_speed_writes_its_table(tmp_path, capsys):
    from admmkit.benchmarks.framework import split_segment_speed
    assert split_segment_speed.main(["--out", str(tmp_path), "--iterations", "100", "--repeats", "1",
                                     "--tv-side", "8"]) == 0
    rows = list(csv.DictReader((tmp_path / "split_speed.csv").open()))
    assert len(rows) == 5 and all(int(r["compiled_iterations"]) > 0 for r in rows)     # every problem compiled
    assert "Command: `admmkit bench split-speed" in (tmp_path / "README.md").read_text()


def test_split_speed_refuses_bad_options(capsys):
    from admmkit.benchmarks.framework import split_segment_speed
    with pytest.raises(SystemExit) as exit_:
        split_segment_speed.main(["--iterations", "5"])
    assert exit_.value.code == 2 and "--iterations" in capsys.readouterr().err
