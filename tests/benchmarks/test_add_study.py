"""One way a study becomes a command (#48 item 4): ``add_study`` in benchmarks/runner/options.py gives every study
its description (cost and needs), the shared options, the packages checked and the cost announced before the
study runs, and the harness's verdict after it."""
import sys
from pathlib import Path

import pytest

from admmkit.benchmarks.runner.costs import COSTS, typical
from admmkit.cli import build_parser, main

#: the studies made commands by add_study, with the function their command calls (monkeypatched here)
STUDIES = {"adaptive": ("admmkit.benchmarks.adaptive.study", "run"),
           "estimators": ("admmkit.benchmarks.adaptive.estimators", "run"),
           "policies": ("admmkit.benchmarks.policies.study", "run"),
           "obstacle": ("admmkit.benchmarks.obstacle.study", "run"),
           "stability": ("admmkit.benchmarks.stability.study", "run"),
           "precision": ("admmkit.benchmarks.precision.study", "run"),
           "rules": ("admmkit.benchmarks.rules.study", "run")}


def bench_parser(name):
    """The parser of ``admmkit bench NAME``."""
    import argparse

    def choices(parser):
        return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    return choices(choices(build_parser(load_all=True))["bench"])[name]


def fake_study(monkeypatch, name, calls):
    """Replace the study behind ``bench NAME`` by one that records its call and writes nothing."""
    import importlib
    module, attr = STUDIES[name]

    def run(*args, **kwargs):
        print("working", file=sys.stderr)
        calls.append((args, kwargs))
        return 0 if name == "obstacle" else []
    monkeypatch.setattr(importlib.import_module(module), attr, run)


@pytest.mark.parametrize("name", sorted(STUDIES))
def test_the_command_is_made_by_add_study(name):
    parser = bench_parser(name)
    assert hasattr(parser.get_default("func"), "needs")
    assert " ".join(typical(f"bench {name}").split()) in " ".join(parser.description.split())
    assert " needs: " in " ".join(parser.description.split("typical:")[1].split())


def bench_commands():
    """{name: parser} of every ``admmkit bench`` command."""
    import argparse

    def choices(parser):
        return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    return choices(choices(build_parser(load_all=True))["bench"])


def test_every_bench_command_is_made_by_add_study_or_own_parser():
    """The two ways: add_study, or own_parser for a study that parses its own options (both check and announce)."""
    commands = bench_commands()
    assert len(commands) > 20
    assert [name for name, parser in commands.items() if not hasattr(parser.get_default("func"), "needs")] == []


def test_the_default_out_is_under_out():
    for name, parser in bench_commands().items():
        out = parser.get_default("out") or parser.get_default("out_file")
        if out is not None:                              # own_parser studies define theirs in their own parser
            assert Path(out).parts[0] == "out", (name, out)


@pytest.mark.parametrize("name", ["adaptive", "estimators", "policies"])
def test_the_cost_is_announced_before_the_study_runs(name, tmp_path, monkeypatch, capsys):
    calls = []
    fake_study(monkeypatch, name, calls)
    # bench adaptive's memory check (tests/benchmarks/test_adaptive_cli.py) passes on any machine here
    monkeypatch.setattr("admmkit.problems.contact.model.memory.available_memory", lambda: 1e12)
    assert main(["bench", name, "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[:2] == [f"bench {name}: {COSTS[f'bench {name}'].text}", "working"]
    assert len(calls) == 1


def test_a_missing_package_is_one_line_before_anything_runs(tmp_path, monkeypatch, capsys):
    calls = []
    fake_study(monkeypatch, "estimators", calls)
    monkeypatch.setitem(sys.modules, "clarabel", None)
    assert main(["bench", "estimators", "--out", str(tmp_path / "out")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and calls == []
    assert err.splitlines() == ['admmkit: error: bench estimators needs clarabel: pip install "clarabel>=0.6"']


def test_bench_rules_asks_for_cvxpy_only_for_the_families_that_need_it(tmp_path, monkeypatch, capsys):
    calls = []
    fake_study(monkeypatch, "rules", calls)
    monkeypatch.setitem(sys.modules, "clarabel", None)
    assert main(["bench", "rules", "--families", "qp", "--out", str(tmp_path / "a")]) == 0
    assert len(calls) == 1
    assert main(["bench", "rules", "--families", "qp,contact", "--out", str(tmp_path / "b")]) == 2
    assert len(calls) == 1
    assert "bench rules needs clarabel" in capsys.readouterr().err
