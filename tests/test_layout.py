"""The layout: imports point one way, benchmarks -> problems -> policies -> admmkit, and commands come by entry point."""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ["admmkit", "policies", "problems", "benchmarks"]   # each may import only those before it


def imported_packages(path: Path) -> set[str]:
    """Top-level packages a module imports (absolute imports only; relative ones stay in the package)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("layer", LAYERS)
def test_imports_point_one_way(layer):
    forbidden = set(LAYERS[LAYERS.index(layer) + 1:])
    wrong = {str(p.relative_to(ROOT)): sorted(imported_packages(p) & forbidden)
             for p in sorted((ROOT / layer).rglob("*.py"))}
    assert {k: v for k, v in wrong.items() if v} == {}


def test_every_command_is_an_entry_point_and_loads():
    from importlib.metadata import entry_points

    from admmkit.cli import GROUP, build_parser
    found = {ep.name: ep.value for ep in entry_points(group=GROUP)}
    assert {"solve.qp", "solve.contact", "solve.obstacle", "demo", "reproduce", "bench.precision"} <= set(found)
    for value in found.values():   # built-in commands live in plug-ins and studies, never in the core
        assert value.split(".")[0] in ("problems", "benchmarks"), value
    build_parser()   # every registrar loads and registers without error


def test_host_imports_no_plug_in():
    assert imported_packages(ROOT / "admmkit" / "cli.py") & {"policies", "problems", "benchmarks"} == set()


@pytest.mark.parametrize("study", ["loop-overhead", "four-problems", "qp-fidelity", "qp-agreement", "friction",
                                   "linsolve"])
def test_studies_with_their_own_options_answer_help_and_bad_options(study, capsys):
    from admmkit.cli import main
    assert main(["bench", study, "--help"]) == 0
    assert "--out" in capsys.readouterr().out
    assert main(["bench", study, "--no-such-option"]) == 2


@pytest.mark.parametrize("layer", LAYERS)
def test_no_module_over_400_lines(layer):
    long = {str(p.relative_to(ROOT)): n for p in sorted((ROOT / layer).rglob("*.py"))
            if (n := len(p.read_text().splitlines())) > 400}
    assert long == {}
