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

    def searched():
        raise AssertionError("every installed package's entry points were read")
    monkeypatch.setattr(cli, "commands", searched)
    assert cli.main(["solve", "qp", "--random", "3", "3", "-q"]) in (0, 1)
    assert "status" in capsys.readouterr().out
    with pytest.raises(AssertionError, match="every installed package"):
        cli.main(["--help"])                     # the list of every command: the full search


def test_own_entry_points_are_importlib_metadatas():
    """The entry points read from admmkit's entry_points.txt are those importlib.metadata gives, and load the same."""
    from admmkit.installed import own_entry_points
    try:
        theirs = {ep.name: ep for ep in distribution("admmkit").entry_points if ep.group == cli.GROUP}
    except PackageNotFoundError:
        pytest.skip("admmkit is not installed")
    mine = own_entry_points(cli.GROUP)
    assert {k: v.value for k, v in mine.items()} == {k: v.value for k, v in theirs.items()}
    assert mine["solve.qp"].load() is theirs["solve.qp"].load()
    assert own_entry_points(cli.GROUP, name="no-such-distribution") is None


def test_own_entry_points_parse_sections_and_comments(tmp_path, monkeypatch):
    from admmkit import installed as own
    info = tmp_path / "demo_pkg-1.0.dist-info"
    info.mkdir()
    (info / "entry_points.txt").write_text("# a comment\n[console_scripts]\nx = a:b\n\n[admmkit.commands]\n"
                                           "solve.x = os.path:join\n; another\nbench.y=os:getcwd [extra]\n")
    monkeypatch.setattr("sys.path", [str(tmp_path / "missing"), str(tmp_path)])
    found = own.own_entry_points("admmkit.commands", name="demo_pkg")
    assert found == {"solve.x": own.EntryPoint("solve.x", "os.path:join"),
                     "bench.y": own.EntryPoint("bench.y", "os:getcwd [extra]")}
    import os
    assert found["solve.x"].load() is os.path.join and found["bench.y"].load() is os.getcwd


def test_a_builtin_command_line_imports_no_importlib_metadata():
    """The console script's process (numpy.testing, which imports importlib.metadata, deferred there)."""
    import subprocess
    import sys
    script = ("import sys\nsys.argv = ['admmkit', 'solve', 'qp', '--random', '3', '3', '-q']\n"
              "from admmkit.cli import main\ncode = main()\nprint(code, 'importlib.metadata' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    try:
        distribution("admmkit")
    except PackageNotFoundError:
        pytest.skip("admmkit is not installed: the full search is the only one")
    assert out.stdout.split()[-2:] == ["0", "False"], out.stderr


@pytest.mark.parametrize("name", ["ngsolve", "netgen-mesher", "numpy", "scipy", "NetGen_Mesher"])
def test_installed_versions_are_importlib_metadatas(name):
    from importlib.metadata import version
    from admmkit.installed import version as installed_version
    try:
        theirs = version(name)
    except PackageNotFoundError:
        theirs = None
    assert installed_version(name) == theirs
    assert installed_version("no-such-distribution") is None
