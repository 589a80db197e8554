"""Fast from the first call (issue #49 items 1-2): the command line loads only the command named, a small QP runs
numpy/scipy without importing numba (the same iterates as the compiled path), one index dtype for every route,
``admmkit warm-up`` and the note at a cold compile."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import admmkit
from admmkit import kernels
from admmkit.cli import COMMAND_HELP, build_parser, commands, main
from admmkit.problems.qp import QP, osqp_settings, random_qp, solve_qp
from admmkit.problems.qp.segment import COMPILED_MIN_SIZE, choose_compiled, compiled_pays

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("ngsolve", "matplotlib", "pyamg", "dask", "pandas", "cvxpy")
needs_numba = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba is not installed")


def fresh(code: str, **env) -> dict:
    """Run ``code`` in a fresh Python process from the repository root; it prints one JSON line, returned."""
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env={**os.environ, "OMP_NUM_THREADS": "1", **env})
    assert out.returncode == 0, out.stderr
    return {**json.loads(out.stdout.strip().splitlines()[-1]), "stderr": out.stderr}


MODULES = f"import json, sys; print(json.dumps({{'loaded': [m for m in {list(HEAVY) + ['numba']!r} if m in sys.modules]}}))"


@pytest.mark.parametrize("argv", [["--help"], ["bench", "--help"], ["solve", "qp", "--random", "5", "5", "-q"]])
def test_the_command_line_imports_only_the_command_named(argv):
    code = ("import contextlib, io, admmkit.cli\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    try: admmkit.cli.main({argv!r})\n"
            "    except SystemExit: pass\n" + MODULES)
    assert fresh(code)["loaded"] == []           # no plug-in's libraries, and no numba for a 5 x 5 QP


@pytest.mark.parametrize("argv", [None, ["--help"], ["bench", "--help"], ["--version"]])
def test_import_admmkit_and_the_hosts_help_load_no_numpy(argv):
    """``import admmkit`` runs the package file only (every public name on first use), and the host's help and
    version need no numpy; ``from admmkit import solve`` loads the loop, with numpy."""
    run = "" if argv is None else ("import contextlib, io, admmkit.cli\n"
                                   "with contextlib.redirect_stdout(io.StringIO()):\n"
                                   f"    try: admmkit.cli.main({argv!r})\n"
                                   "    except SystemExit: pass\n")
    probe = "import json, sys; print(json.dumps({'numpy': 'numpy' in sys.modules}))"
    assert fresh("import admmkit\n" + run + probe)["numpy"] is False
    assert fresh("from admmkit import solve\n" + probe)["numpy"] is True


def test_every_public_name_of_admmkit_resolves():
    assert set(admmkit.__all__) <= set(dir(admmkit))
    for name in admmkit.__all__:
        assert getattr(admmkit, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        admmkit.nope


def test_help_lists_every_command_with_its_registrars_line(capsys):
    parser = build_parser(load_all=True)
    seen = {}
    for action in parser._subparsers._group_actions:
        for choice in action._choices_actions:
            seen[choice.dest] = choice.help
            sub = action._name_parser_map[choice.dest]._subparsers
            for inner in (sub._group_actions if sub else []):
                seen.update({f"{choice.dest}.{c.dest}": c.help for c in inner._choices_actions})
    for path, ep in commands().items():
        if ep.value.startswith("admmkit."):      # a built-in command: its line is in the table, the registrar's own
            assert COMMAND_HELP[path] == seen[path], path
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "solve" in out and "bench" in out and COMMAND_HELP["demo"][:30] in " ".join(out.split())


def test_a_bench_command_loads_for_its_help_and_a_misspelt_one_is_one_line(capsys):
    assert main(["bench", "qp-fidelity", "--help"]) == 0
    assert "--data" in capsys.readouterr().out                 # the study's own options: its registrar loaded
    assert main(["bench", "first-cal"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "did you mean first-call?" in err


def test_a_small_qp_runs_numpy_without_numba_and_a_large_one_compiled():
    code = ("from admmkit.problems.qp import random_qp, solve_qp\n"
            "res = solve_qp(random_qp(5, 5, seed=1))\n"
            "import json, sys\n"
            "print(json.dumps({'numba': 'numba' in sys.modules, 'status': str(res.status),\n"
            "                  'compiled': res.counters.get('compiled_iterations', 0)}))")
    out = fresh(code)
    assert out["numba"] is False and out["compiled"] == 0 and "converged" in out["status"]
    assert compiled_pays(500, 400, COMPILED_MIN_SIZE) == kernels.AVAILABLE


def test_a_process_that_ran_compiled_keeps_compiled_code_for_small_qps_too():
    code = ("from admmkit.problems.qp import random_qp, solve_qp\n"
            "from admmkit.problems.qp.segment import compiled_pays\n"
            "before = compiled_pays(5, 5, 40)\n"
            "solve_qp(random_qp(5, 5, seed=1), compiled=True)\n"
            "res = solve_qp(random_qp(5, 5, seed=2))\n"
            "import json; print(json.dumps({'before': before, 'after': compiled_pays(5, 5, 40),\n"
            "                               'compiled': res.counters.get('compiled_iterations', 0)}))")
    out = fresh(code)
    assert out["before"] is False and out["after"] is kernels.AVAILABLE
    assert (out["compiled"] > 0) is kernels.AVAILABLE


@needs_numba
@pytest.mark.parametrize("seed", [2, 3])
def test_every_setting_gives_the_same_iterates(seed):
    qp = random_qp(20, 30, seed=seed)
    runs = {flag: solve_qp(qp, compiled=flag) for flag in ("auto", True, False)}
    assert runs[True].counters.get("compiled_iterations", 0) > 0 and "compiled_iterations" not in runs[False].counters
    for flag in ("auto", False):
        a, b = runs[True], runs[flag]
        assert a.iterations == b.iterations and a.status == b.status
        for u, v in ((a.x, b.x), (a.y, b.y), (a.z, b.z)):
            assert np.array_equal(u.view(np.int64), v.view(np.int64))


@needs_numba
def test_a_kernel_as_python_gives_the_compiled_bits():
    from admmkit.problems.qp.ruiz_kernel import ruiz_steps
    from admmkit.problems.qp.scaling import MAX_SCALING, MIN_SCALING
    qp = random_qp(30, 40, seed=4)
    P, A = qp.P, qp.A
    out = {}
    for flag in (False, True):
        Pd, Ad, q, D, E = P.data.copy(), A.data.copy(), qp.q.copy(), np.ones(qp.n), np.ones(qp.m)
        with kernels.compiled_code(flag):
            c = ruiz_steps(10, MIN_SCALING, MAX_SCALING, Pd, P.indices, P.indptr, Ad, A.indices, A.indptr, q, D, E)
        out[flag] = np.concatenate([Pd, Ad, q, D, E, [c]])
    assert np.array_equal(out[False].view(np.int64), out[True].view(np.int64))


def test_the_setting_is_checked():
    with pytest.raises(ValueError, match="compiled must be 'auto', True or False"):
        osqp_settings(compiled="yes")
    assert osqp_settings().compiled == "auto"
    small = random_qp(5, 5, seed=0)
    assert choose_compiled(False, small)[0] is False           # every iteration in Python
    assert choose_compiled(True, small) == (kernels.AVAILABLE, kernels.AVAILABLE)


def test_one_index_dtype_for_every_route():
    qp = random_qp(8, 6, seed=5)
    P, A = qp.P.copy(), qp.A.copy()
    for M in (P, A):
        M.indices, M.indptr = M.indices.astype(np.int64), M.indptr.astype(np.int64)
    wide = QP(P, qp.q, A, qp.l, qp.u)                      # as cvxpy hands them over
    for M in (wide.P, wide.A):
        assert M.indices.dtype == np.int32 and M.indptr.dtype == np.int32
    assert P.indices.dtype == np.int64                     # the user's matrix is not changed
    assert np.array_equal(solve_qp(wide).x, solve_qp(qp).x)


def test_import_admmkit_loads_no_numba():
    assert fresh("import admmkit, admmkit.linalg.compiled, admmkit.problems.qp.segment\n" + MODULES)["loaded"] == []


@needs_numba
def test_a_cold_compile_says_so_once_and_a_cached_one_does_not(tmp_path):
    code = ("import numpy as np\nfrom admmkit import kernels\n"
            "with kernels.compiled_code(True):\n"
            "    ok = kernels.all_finite(np.ones(3), 0, 3)\n"
            "import json; print(json.dumps({'ok': bool(ok)}))")
    cold = fresh(code, NUMBA_CACHE_DIR=str(tmp_path))
    assert cold["ok"] and cold["stderr"].count("admmkit warm-up") == 1
    warm = fresh(code, NUMBA_CACHE_DIR=str(tmp_path))
    assert warm["ok"] and "admmkit warm-up" not in warm["stderr"]


@needs_numba
def test_warm_up_compiles_the_groups(capsys):
    from admmkit.benchmarks.framework import warm_up
    parser = admmkit.cli.Parser(prog="admmkit")
    warm_up.register(parser.add_subparsers())
    args = parser.parse_args(["warm-up"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert out.count(" ready in ") == len(warm_up.GROUPS) and "kernels compiled or loaded" in out
    assert warm_up.kernels_ready() >= 10
    assert parser._subparsers._group_actions[0]._choices_actions[0].help == COMMAND_HELP["warm-up"]
    # the finite element group reaches a kernel of every V-cycle level kind and of the set-ups that precede them
    from admmkit.linalg import (amg_finest3d, cg, vcycle, vcycle_blockgs3d, vcycle_blocks, vcycle_blocks3)
    from admmkit.problems.contact.model import stiffness3d
    from admmkit.problems.contact.solvers import condensed_segment, dissection
    reached = {f"{k.__module__}.{k.__name__}": bool(getattr(k, "_dispatcher", k).signatures) for k in (
        vcycle._gauss_seidel_backward, vcycle_blocks.forward_restrict, vcycle_blocks3.forward_restrict,
        vcycle_blockgs3d.block_forward_restrict, amg_finest3d.galerkin_product, cg._step_kernel,
        dissection._dissect, stiffness3d._element_blocks, condensed_segment.segment_kernel)}
    assert all(reached.values()), reached
