"""A command line naming a built-in command reads admmkit's own entry points, not every package's (issue #49)."""
from importlib.metadata import PackageNotFoundError, distribution

import pytest

import admmkit.cli.host as cli


def test_builtin_named():
    assert cli.builtin_named(["solve", "contact", "--h", "1/40"]) == "solve.contact"
    assert cli.builtin_named(["bench", "contact", "--out", "x.md"]) == "bench.contact"
    assert cli.builtin_named(["demo"]) == "demo"
    for argv in ([], ["--help"], ["solve", "--help"], ["solve", "nothing"], ["--version"]):
        assert cli.builtin_named(argv) is None


def test_a_builtin_command_searches_no_other_package(monkeypatch, capsys):
    try:
        distribution("admmkit")
    except PackageNotFoundError:
        pytest.skip("admmkit is not installed: the full search is the only one")

    def searched(**_):
        raise AssertionError("every installed package's entry points were read")
    monkeypatch.setattr(cli, "entry_points", searched)
    assert cli.main(["solve", "qp", "--random", "3", "3", "-q"]) in (0, 1)
    assert "status" in capsys.readouterr().out
    with pytest.raises(AssertionError, match="every installed package"):
        cli.main(["--help"])                     # the list of every command: the full search
