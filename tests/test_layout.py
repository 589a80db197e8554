"""The layout: one import name, imports that point one way, no import circle.

The repository keeps four folders side by side (``admmkit/``, ``policies/``,
``problems/``, ``benchmarks/``); the last three are the subpackages
``admmkit.policies``, ``admmkit.problems`` and ``admmkit.benchmarks``.  Each
layer may import only the layers before it: benchmarks -> problems -> policies
-> admmkit (the core).
"""
import ast
import subprocess
import sys
from importlib.metadata import distributions
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ["admmkit", "policies", "problems", "benchmarks"]   # each may import only those before it
SUBPACKAGES = LAYERS[1:]


def layer_files(layer: str) -> list[Path]:
    """The Python files of a layer (the core's folder is admmkit/, the others their own)."""
    return sorted((ROOT / layer).rglob("*.py"))


def module_name(path: Path) -> str:
    """The dotted import name of a file in the repository, as installed (``admmkit.problems.qp.cli``)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts if parts[0] == "admmkit" else ["admmkit", *parts])


def imported_modules(path: Path) -> set[str]:
    """The absolute dotted names a module imports (relative imports resolved against its package)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module_name(path).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[:len(package) - node.level + 1] + ([base] if base else []))
            names |= {f"{base}.{alias.name}" for alias in node.names}   # a module, or a name in module base
    return names


def layer_of(name: str) -> str | None:
    """The layer an imported name belongs to (None for a module outside admmkit)."""
    parts = name.split(".")
    if parts[0] in SUBPACKAGES:
        return "top-level " + parts[0]        # the folder imported by its folder name: always wrong
    if parts[0] != "admmkit":
        return None
    return parts[1] if len(parts) > 1 and parts[1] in SUBPACKAGES else "admmkit"


@pytest.mark.parametrize("layer", LAYERS)
def test_imports_point_one_way(layer):
    allowed = set(LAYERS[:LAYERS.index(layer) + 1])
    wrong = {}
    for path in layer_files(layer):
        bad = sorted({layer_of(n) for n in imported_modules(path)} - allowed - {None})
        if bad:
            wrong[str(path.relative_to(ROOT))] = bad
    assert wrong == {}


def import_graph() -> dict[str, set[str]]:
    """module -> the admmkit modules it imports (a package import counts as its __init__)."""
    files = {module_name(p): p for layer in LAYERS for p in layer_files(layer)}
    graph = {}
    for name, path in files.items():
        graph[name] = {n if n in files else n.rsplit(".", 1)[0] for n in imported_modules(path)
                       if n.startswith("admmkit")} & set(files)
        graph[name].discard(name)
    return graph


def test_no_import_circle():
    """Tarjan's strongly connected components of the import graph: every one a single module.

    An ``__init__`` that re-exports its package's modules is the package's face,
    not a circle: the edges from a package's own modules to their ``__init__``
    (``from . import x``, ``from .. import y``) are left out.
    """
    graph = import_graph()
    for name, deps in graph.items():
        graph[name] = {d for d in deps if not (name.startswith(d + ".") and d != "admmkit")}
    index, low, stack, on_stack, circles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert circles == []


def test_installed_package_owns_one_import_name():
    """site-packages gains ``admmkit`` and nothing else of ours (the dist-info and the script aside)."""
    installed = [d for d in distributions() if d.metadata["Name"] == "admmkit" and d.read_text("RECORD")]
    assert len(installed) == 1
    files = installed[0].files
    finder = [f for f in files if f.name.startswith("__editable__") and f.suffix == ".py"]
    if finder:                 # pip install -e .: the editable finder's mapping is what site-packages provides
        import ast
        source = finder[0].locate().read_text()
        mapping = ast.literal_eval(source.split("MAPPING: dict[str, str] = ", 1)[1].split("\n", 1)[0])
        assert {name.split(".")[0] for name in mapping} == {"admmkit"}
        assert {"admmkit.policies", "admmkit.problems", "admmkit.benchmarks"} <= set(mapping)
        return
    top = {f.parts[0] for f in files if not f.parts[0].startswith("..") and not f.parts[0].endswith(".dist-info")}
    assert top == {"admmkit"}
    names = {".".join(f.with_suffix("").parts[:3]) for f in files if f.suffix == ".py"}
    assert {"admmkit.policies.summable", "admmkit.problems.qp", "admmkit.problems.contact"} <= names
    assert any(n.startswith("admmkit.benchmarks.") for n in names)


def test_source_checkout_resolves_the_subpackages_from_its_own_folders():
    """From the repository root (on sys.path first, as under ``python -m pytest``), admmkit.policies etc.
    are the checkout's folders, the same files an installed copy maps."""
    code = ("import admmkit, admmkit.policies, admmkit.problems.qp, admmkit.benchmarks; "
            "print(admmkit.__file__); print(admmkit.policies.__file__); print(admmkit.problems.qp.__file__); "
            "print(admmkit.make_policy('summable'))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    lines = out.splitlines()
    assert lines[0] == str(ROOT / "admmkit" / "__init__.py")
    assert lines[1] == str(ROOT / "policies" / "__init__.py")
    assert lines[2] == str(ROOT / "problems" / "qp" / "__init__.py")
    assert lines[3].startswith("Summable(")


def test_every_command_is_an_entry_point_and_loads():
    from importlib.metadata import entry_points

    from admmkit.cli import GROUP, build_parser
    found = {ep.name: ep.value for ep in entry_points(group=GROUP)}
    assert {"solve.qp", "solve.contact", "solve.obstacle", "demo", "reproduce", "bench.precision"} <= set(found)
    for value in found.values():   # built-in commands live in plug-ins and studies, never in the core
        assert value.split(".")[:2] in (["admmkit", "problems"], ["admmkit", "benchmarks"]), value
    build_parser(load_all=True)   # every registrar loads and registers without error


def test_host_imports_no_plug_in():
    for path in (ROOT / "admmkit" / "cli").glob("*.py"):
        assert {layer_of(n) for n in imported_modules(path)} <= {"admmkit", None}, path.name


#: the core's subpackages, by job (docs/layout.md)
CORE_JOBS = ["loop", "blocks", "linalg", "fe", "cli"]


def test_core_holds_a_dozen_modules_and_the_rest_by_job():
    """admmkit/ holds at most a dozen modules directly; every folder in it is one of the jobs."""
    direct = sorted(p.name for p in (ROOT / "admmkit").glob("*.py"))
    assert len(direct) <= 12, direct
    folders = sorted(p.name for p in (ROOT / "admmkit").iterdir() if p.is_dir() and not p.name.startswith("__"))
    assert folders == sorted(CORE_JOBS)


def reached(graph: dict[str, set[str]], start: set[str]) -> set[str]:
    """Every module imported from ``start``, directly or through others."""
    seen, todo = set(), list(start)
    while todo:
        for w in graph.get(todo.pop(), ()):
            if w not in seen:
                seen.add(w)
                todo.append(w)
    return seen


def test_the_loop_imports_no_linear_algebra():
    """admmkit.loop reaches neither admmkit.linalg nor the building blocks, not even through another module
    (a problem brings its own linear algebra; the loop only calls its steps)."""
    graph = import_graph()
    loop = {name for name in graph if name.startswith("admmkit.loop")}
    assert loop
    bad = sorted(n for n in reached(graph, loop) if n.split(".")[1] in ("linalg", "blocks"))
    assert bad == []


def unit(name: str) -> str:
    """The unit of docs/layout.md's arrows a module belongs to (a core job, a layer, or a layer's folder)."""
    parts = name.split(".")
    if len(parts) > 1 and parts[1] in CORE_JOBS:
        return f"admmkit.{parts[1]}"
    if len(parts) > 1 and parts[1] in SUBPACKAGES:
        return ".".join(parts[1:3]) if len(parts) > 2 and (ROOT / parts[1] / parts[2]).is_dir() else parts[1]
    return "admmkit"


def arrows() -> str:
    """The block of docs/layout.md between its ``arrows`` markers, drawn from the import graph."""
    graph = import_graph()
    edges: dict[str, set[str]] = {}
    for name, deps in graph.items():
        edges.setdefault(unit(name), set())
        edges[unit(name)] |= {unit(d) for d in deps} - {unit(name)}
    order = ["admmkit", *[f"admmkit.{j}" for j in CORE_JOBS]]
    units = order + sorted(set(edges) - set(order))
    width = max(map(len, units)) + 2
    lines = [f"{u:<{width}}-> {', '.join(sorted(edges.get(u, ()), key=units.index)) or '(nothing of admmkit)'}"
             for u in units if u in edges]
    return "\n".join(["```", *lines, "```"])


def test_a_plug_in_imports_no_other_plug_in():
    """problems.X never imports problems.Y: what two plug-ins share lives in problems/ itself (fe.py, expressions.py)."""
    graph = import_graph()
    wrong = {name: sorted({unit(d) for d in deps} - {unit(name)}) for name, deps in graph.items()
             if unit(name).startswith("problems.")}
    assert {n: [u for u in us if u.startswith("problems.")] for n, us in wrong.items()
            if any(u.startswith("problems.") for u in us)} == {}


def test_layout_page_draws_the_current_arrows():
    """docs/layout.md's arrows are those of the code (``python tests/test_layout.py`` prints the block)."""
    text = (ROOT / "docs" / "layout.md").read_text()
    block = text.split("<!-- arrows: begin -->\n", 1)[1].split("\n<!-- arrows: end -->", 1)[0]
    assert block == arrows()


@pytest.mark.parametrize("study", ["loop-overhead", "four-problems", "qp-fidelity", "qp-agreement", "friction",
                                   "linsolve", "anderson-cost"])
def test_studies_with_their_own_options_answer_help_and_bad_options(study, capsys):
    from admmkit.cli import main
    assert main(["bench", study, "--help"]) == 0
    assert "--out" in capsys.readouterr().out
    assert main(["bench", study, "--no-such-option"]) == 2


if __name__ == "__main__":
    print(arrows())
