"""bench adaptive's command line: the memory it needs, checked before any work."""
import pytest


def test_bench_adaptive_refuses_the_hertz_scenes_where_memory_is_short():
    from admmkit.benchmarks.adaptive.cli import HERTZ_REFERENCE_BYTES, check_memory
    scenes = ("obstacle", "ex1", "ex2", "hertz")
    with pytest.raises(ValueError, match=r"Hertz scenes' reference .* killed for memory .* this check asks for 25 "
                                         r"GB, 20.0 GB available here; run --scenes obstacle ex1 ex2, or --quick"):
        check_memory(False, scenes, 20e9)
    with pytest.raises(ValueError, match="run it on a larger machine, or --quick"):
        check_memory(False, ("hertz",), 20e9)
    check_memory(True, scenes, 20e9)                              # --quick: the coarse reference fits
    check_memory(False, ("obstacle", "ex1"), 20e9)                # no Hertz
    check_memory(False, scenes, HERTZ_REFERENCE_BYTES)            # enough


def test_the_refusal_is_one_line_and_exit_2_before_any_work(tmp_path, monkeypatch, capsys):
    from admmkit.benchmarks.adaptive import study
    from admmkit.cli import main
    calls = []
    monkeypatch.setattr(study, "run", lambda *a, **k: calls.append(a) or [])
    monkeypatch.setattr("admmkit.problems.contact.model.memory.available_memory", lambda: 20e9)
    assert main(["bench", "adaptive", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert calls == [] and err[-1].startswith("admmkit: error: bench adaptive: the Hertz scenes' reference")
    assert main(["bench", "adaptive", "--scenes", "ex1", "--out", str(tmp_path / "out")]) == 0 and len(calls) == 1
