"""Studies announce long runs (issue #47 item 3): one table of costs (benchmarks/runner/costs.py) that the
``typical:`` line of each study's help and the announcement on stderr both read."""
import sys

import pytest

from admmkit.benchmarks.runner.costs import COSTS, UNRECORDED, announce, typical
from admmkit.benchmarks.runner.options import ALIASES
from admmkit.cli import build_parser, main

#: the studies whose registration lives in benchmarks/*/cli.py (their description reads the table)
REGISTERED_IN_CLI = ["reproduce paper", "bench paper-compare", "bench contact", "bench contact-schur", "bench hertz",
                     "bench scale", "bench amg-crossover", "bench contact3d", "bench executors", "bench qp",
                     "bench rules", "bench precision", "bench stability", "bench policies", "bench obstacle",
                     "bench adaptive", "bench estimators"]


def run(argv, capsys):
    """(exit code, stdout, stderr) of ``admmkit ARGV``."""
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def subparsers(parser):
    """{name: parser} of ``parser``'s sub-commands."""
    import argparse
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def test_every_study_has_a_cost():
    top = subparsers(build_parser(load_all=True))
    studies = {f"bench {name}" for name in subparsers(top["bench"])} | {"reproduce paper"}
    assert {ALIASES.get(s, s) for s in studies} <= set(COSTS), sorted(studies - set(COSTS) - set(ALIASES))


@pytest.mark.parametrize("command", REGISTERED_IN_CLI)
def test_the_help_reads_the_table(command):
    top = subparsers(build_parser(load_all=True))
    group, name = command.split()
    parser = top["reproduce"] if group == "reproduce" else subparsers(top["bench"])[name]
    assert " ".join(typical(command).split()) in " ".join(parser.description.split())


def test_every_cost_says_time_and_memory_or_that_memory_was_not_recorded():
    for command, cost in COSTS.items():
        assert "GB" in cost.text or UNRECORDED in cost.text, command
        assert cost.text[0].isalpha() and not cost.text.endswith("."), command


def test_a_short_study_is_not_announced(capsys):
    announce("bench split-speed")
    announce("bench no-such-study")
    assert capsys.readouterr().err == ""


def test_a_refusal_stays_one_line_without_the_announcement(monkeypatch, capsys):
    """bench scale without clarabel: the one-line refusal alone (the packages are checked before the cost is
    announced), nothing run."""
    from admmkit.benchmarks.contact import scale
    monkeypatch.setitem(sys.modules, "clarabel", None)
    monkeypatch.setattr(scale, "run_scale_bench", lambda **kw: pytest.fail("bench scale ran without clarabel"))
    code, out, err = run(["bench", "scale"], capsys)
    assert code == 2 and out == ""
    assert err.splitlines() == ['admmkit: error: bench scale needs clarabel: pip install "clarabel>=0.6"']


def test_the_announcement_of_bench_scale(monkeypatch, capsys):
    from admmkit.benchmarks.contact import scale

    def run_scale_bench(**kwargs):
        print("working", file=sys.stderr)
        return []
    monkeypatch.setattr(scale, "run_scale_bench", run_scale_bench)
    code, out, err = run(["bench", "scale"], capsys)
    assert err.splitlines() == [f"bench scale: {COSTS['bench scale'].text}", "working"]
    assert "2.4 GB peak" in err and "on 2 cores" in err


@pytest.mark.parametrize("command", [c for c in REGISTERED_IN_CLI if c != "reproduce paper"])
def test_every_registered_study_checks_and_announces_before_its_work(command):
    """Each study's function begins with needs(args, ...), which checks its packages and then announces it, or
    is made a command by add_study, which calls it before the study (tests/benchmarks/test_add_study.py)."""
    import inspect
    top = subparsers(build_parser(load_all=True))
    func = subparsers(top["bench"])[command.split()[1]].get_default("func")
    if hasattr(func, "needs"):
        return
    body = inspect.getsource(inspect.unwrap(func)).split("\n", 1)[1].lstrip()
    assert body.startswith("needs(args"), body[:80]


def test_the_announcement_comes_before_any_work(tmp_path, monkeypatch, capsys):
    from admmkit.benchmarks.contact import contact_speed

    def run_bench(**kwargs):
        print("working", file=sys.stderr)
        return []
    monkeypatch.setattr(contact_speed, "run_bench", run_bench)
    code, out, err = run(["bench", "contact", "--out", str(tmp_path / "speed.md")], capsys)
    assert code == 0
    assert err.splitlines()[:2] == [f"bench contact: {COSTS['bench contact'].text}", "working"]
    assert err.startswith("bench contact: about 4-7 min") and "10.2 GB peak" in err


def test_an_own_parser_study_is_announced_but_not_its_help(monkeypatch, capsys):
    from admmkit.benchmarks.contact import friction_validation

    def fake_main(argv, prog):
        print(f"working {argv}", file=sys.stderr)
        return 0
    monkeypatch.setattr(friction_validation, "main", fake_main)
    code, out, err = run(["bench", "friction", "--quick"], capsys)
    assert code == 0
    assert err.splitlines() == [f"bench friction: {COSTS['bench friction'].text}", "working ['--quick']"]
    code, out, err = run(["bench", "friction", "--help"], capsys)
    assert err.splitlines() == ["working ['--help']"]


def test_report_only_runs_nothing_and_announces_nothing(tmp_path, capsys):
    code, out, err = run(["bench", "precision", "--out", str(tmp_path), "--report-only"], capsys)
    assert COSTS["bench precision"].text not in err and "admmkit: error:" in err
