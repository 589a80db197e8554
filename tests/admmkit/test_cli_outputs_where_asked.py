"""Outputs where asked (issue #47 item 3) and silent inputs (issue #46): a study's --out FILE writes that file,
reproduce paper writes under out/paper and says what it wrote, the adaptive loop's options refuse to be
ignored, a closed pipe ends quietly, ``--json -`` keeps the summary off stdout, and ``sys.exit`` in a rule
is an error, not a silent end."""
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from admmkit.cli import EXIT_BAD_INPUT, EXIT_CLOSED_PIPE, main

from tests.cli_run import one_error_line, run

ROOT = Path(__file__).resolve().parents[2]
QP = ["solve", "qp", "--random", "20", "12"]


# ---------------------------------------------------------------- the adaptive loop's options need --target-error
@pytest.mark.parametrize("command", ["contact", "obstacle"])
@pytest.mark.parametrize("flags, needle", [
    (["--theta", "2", "--max-levels", "0"], "--theta, --max-levels need --target-error"),
    (["--max-unknowns", "100"], "--max-unknowns needs --target-error"),
    (["--theta", "0.3"], "--theta needs --target-error"),
])
def test_adaptive_flags_without_target_error_are_refused(command, flags, needle, capsys):
    code, out, err = run(["solve", command, *flags], capsys)
    assert code == EXIT_BAD_INPUT and out == ""
    assert needle in one_error_line(err)


def test_adaptive_options_fill_the_plugins_defaults():
    """Not given, the loop's options take the plug-in's defaults (contact 20 levels, obstacle 30)."""
    from admmkit.cli import build_parser
    from admmkit.cli.adaptive import adaptive_options
    for command, levels in (("contact", 20), ("obstacle", 30)):
        args = build_parser().parse_args(["solve", command, "--target-error", "0.1"])
        assert (args.theta, args.max_levels, args.max_unknowns) == (None, None, None)
        options = adaptive_options(args)
        assert (options["theta"], options["max_levels"], options["max_unknowns"]) == (0.5, levels, 2_000_000)
        args = build_parser().parse_args(["solve", command, "--target-error", "0.1", "--theta", "0.3"])
        assert adaptive_options(args)["theta"] == 0.3


# ---------------------------------------------------------------- a closed pipe, --json -, sys.exit in user code
def closed_pipe_run(argv):
    """Run ``python -m admmkit ARGV`` with a standard output whose reader has already left (``| head`` done)."""
    r, w = os.pipe()
    os.close(r)
    try:
        return subprocess.run([sys.executable, "-m", "admmkit", *argv], stdout=w, stderr=subprocess.PIPE,
                              text=True, cwd=ROOT, env={**os.environ, "OMP_NUM_THREADS": "1"}, timeout=300)
    finally:
        os.close(w)


def test_a_closed_pipe_ends_quietly_with_141():
    done = closed_pipe_run([*QP, "-q"])
    assert done.returncode == EXIT_CLOSED_PIPE == 141
    assert done.stderr == ""                     # no 'Broken pipe' error, no 'Exception ignored' at shutdown


def test_a_broken_pipe_inside_main_is_quiet(monkeypatch, capsys):
    """The same in-process: a stdout that raises BrokenPipeError -> 141, nothing on stderr, stdout silenced."""
    class ClosedPipe:
        buffer = None

        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            pass
    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    assert main([*QP, "-q"]) == EXIT_CLOSED_PIPE
    assert not isinstance(sys.stdout, ClosedPipe)           # now the null device: the last flush says nothing
    sys.stdout.close()
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("flag", ["--json", "--csv", "--history"])
def test_output_to_stdout_puts_the_text_on_stderr(flag, capsys):
    code, out, err = run([*QP, "-q", flag, "-"], capsys)
    assert code == 0
    assert "status       converged" in err and "status       " not in out and "problem      " not in out
    if flag == "--json":
        assert json.loads(out)["result"]["status"] == "converged"    # stdout holds the JSON alone
    else:
        assert out.splitlines()[0].count(",") >= 1                    # a CSV header first, no summary line


def test_without_stdout_output_the_summary_stays_on_stdout(capsys):
    code, out, err = run([*QP, "-q"], capsys)
    assert code == 0 and "status       converged" in out


def test_json_to_stdout_pipes_into_a_json_reader():
    done = subprocess.run([sys.executable, "-m", "admmkit", *QP, "-q", "--json", "-"], capture_output=True,
                          text=True, cwd=ROOT, env={**os.environ, "OMP_NUM_THREADS": "1"}, timeout=300)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["result"]["status"] == "converged"
    assert "status       converged" in done.stderr


RULE_THAT_EXITS = """import sys
from admmkit import Policy


class Quit(Policy):
    def update(self, rec):
        sys.exit({code})
"""


@pytest.mark.parametrize("code", [0, 3])
def test_sys_exit_in_a_rule_is_an_error(code, tmp_path, capsys):
    rule = tmp_path / f"quit{code}.py"
    rule.write_text(RULE_THAT_EXITS.format(code=code))
    exit_code, out, err = run([*QP, "-q", "--policy", f"{rule}:Quit"], capsys)
    assert exit_code == EXIT_BAD_INPUT
    assert one_error_line(err) == f"admmkit: error: user code called sys.exit({code}) during the run"


# ---------------------------------------------------------------- bench contact / contact-schur --out FILE
@pytest.fixture
def fake_contact_runs(monkeypatch):
    """The contact studies' runners replaced by ones that write their --out file at once: {study: out given}."""
    from admmkit.benchmarks.contact import contact_speed, schur_study
    given = {}

    def fake(name):
        def run(out=None, **kwargs):
            given[name] = out
            Path(out).parent.mkdir(parents=True, exist_ok=True)
            Path(out).write_text(f"# {name}\n")
            return []
        return run
    monkeypatch.setattr(contact_speed, "run_bench", fake("contact"))
    monkeypatch.setattr(schur_study, "run_study", fake("contact-schur"))
    return given


@pytest.mark.parametrize("study", ["contact", "contact-schur"])
def test_bench_contact_out_names_an_existing_markdown_file(study, tmp_path, fake_contact_runs, capsys):
    """The README's own command, ``bench contact --out docs/results/contact_speed.md``, once the file exists."""
    target = tmp_path / "docs" / "results" / "contact_speed.md"
    target.parent.mkdir(parents=True)
    target.write_text("committed\n")
    code, out, err = run(["bench", study, "--out", str(target)], capsys)
    assert code == 0, err
    assert fake_contact_runs[study] == str(target) and target.read_text() == f"# {study}\n"
    assert out.splitlines() == [f"wrote {target}"]
    assert sorted(p.name for p in target.parent.iterdir()) == ["contact_speed.md"]     # nothing beside it


@pytest.mark.parametrize("study, default", [("contact", "out/contact/contact_speed.md"),
                                            ("contact-schur", "out/contact/contact_schur.md")])
def test_bench_contact_out_file_in_a_new_folder_and_by_default(study, default, tmp_path, fake_contact_runs, capsys,
                                                               monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(["bench", study, "--out", "new/sub/speed.md"], capsys)
    assert code == 0, err
    assert (tmp_path / "new" / "sub" / "speed.md").is_file()
    code, out, err = run(["bench", study], capsys)                      # the default, in a fresh folder
    assert code == 0, err
    assert fake_contact_runs[study] == default and (tmp_path / default).is_file()
    assert out.splitlines() == [f"wrote {default}"]


@pytest.mark.parametrize("study", ["contact", "contact-schur"])
def test_bench_contact_out_refuses_a_folder(study, tmp_path, fake_contact_runs, capsys):
    code, out, err = run(["bench", study, "--out", str(tmp_path)], capsys)
    assert code == EXIT_BAD_INPUT and study not in fake_contact_runs and out == ""
    assert "is a directory; give a file name" in one_error_line(err.splitlines()[-1])


def test_bench_contact_help_says_out_is_the_one_file(capsys):
    from admmkit.cli import plain
    assert main(["bench", "contact", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--out FILE the Markdown file to write, the only file written; its folder is created" in plain(text)


# ---------------------------------------------------------------- reproduce paper: out/paper, and what it wrote
@pytest.fixture
def fake_reproduction(monkeypatch):
    """run_reproduction replaced by one that writes two files into ``out``: {"out": the folder given}."""
    from admmkit.benchmarks.contact import paper
    given = {}

    def run_reproduction(out="out/paper", **kwargs):
        given["out"] = out
        Path(out).mkdir(parents=True, exist_ok=True)
        files = [Path(out) / "table1_ex1_time.md", Path(out) / "README.md"]
        for f in files:
            f.write_text("x\n")
        return {"runs": [], "references": {}, "files": files, "wall_time": 0.0}
    monkeypatch.setattr(paper, "run_reproduction", run_reproduction)
    return given


def test_reproduce_paper_writes_under_out_paper_and_lists_the_files(tmp_path, fake_reproduction, monkeypatch,
                                                                     capsys):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(["reproduce", "paper", "-q"], capsys)
    assert code == 0, err
    assert fake_reproduction["out"] == "out/paper"
    assert out.splitlines() == [f"wrote {Path('out/paper') / 'table1_ex1_time.md'}",
                                f"wrote {Path('out/paper') / 'README.md'}"]
    assert not (tmp_path / "docs").exists()


def test_reproduce_paper_out_refreshes_the_committed_copy(tmp_path, fake_reproduction, monkeypatch, capsys):
    """README: ``admmkit reproduce paper --out docs/results/paper`` (an existing folder)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "docs" / "results" / "paper").mkdir(parents=True)
    code, out, err = run(["reproduce", "paper", "--out", "docs/results/paper", "-q"], capsys)
    assert code == 0, err
    assert fake_reproduction["out"] == "docs/results/paper"
    assert f"wrote {Path('docs/results/paper') / 'README.md'}" in out.splitlines()


# ---------------------------------------------------------------- the contact reference says who made it
@pytest.fixture(scope="module")
def ex1_ops():
    from admmkit.problems.contact.model.assembly import assemble
    from admmkit.problems.contact.model.scene import example1
    return assemble(example1(1 / 10))


def test_the_reference_is_clarabels_when_it_is_there(ex1_ops):
    from admmkit.problems.contact.validation.reference import reference_solution
    with warnings.catch_warnings():
        warnings.simplefilter("error")                                  # no fallback warning
        ref = reference_solution(ex1_ops)
    assert ref.solver.startswith("cvxpy + Clarabel")
    assert ref.info == {"solver": ref.solver, "fallback": None}


def test_the_sadmm_fallback_is_loud_without_clarabel(ex1_ops, monkeypatch):
    from admmkit.problems.contact.validation.reference import TIGHT_SADMM, reference_solution
    monkeypatch.setitem(sys.modules, "clarabel", None)
    with pytest.warns(RuntimeWarning, match="Clarabel is not installed; the reference is the tight SADMM run"):
        ref = reference_solution(ex1_ops)
    assert ref.solver == TIGHT_SADMM
    assert ref.info == {"solver": TIGHT_SADMM, "fallback": "Clarabel is not installed"}


def test_the_sadmm_fallback_is_loud_when_clarabel_fails(ex1_ops, monkeypatch):
    import cvxpy as cp

    from admmkit.problems.contact.validation.reference import TIGHT_SADMM, reference_solution

    def fail(self, *args, **kwargs):
        raise cp.error.SolverError("Solver 'CLARABEL' failed.")
    monkeypatch.setattr(cp.Problem, "solve", fail)
    with pytest.warns(RuntimeWarning, match=r"Clarabel failed \(SolverError: Solver 'CLARABEL' failed.\)"):
        ref = reference_solution(ex1_ops)
    assert ref.info["solver"] == TIGHT_SADMM and ref.info["fallback"].startswith("Clarabel failed")


def test_bench_scale_refuses_at_once_without_clarabel(monkeypatch, capsys):
    from admmkit.benchmarks.contact import scale
    monkeypatch.setitem(sys.modules, "clarabel", None)
    monkeypatch.setattr(scale, "run_scale_bench", lambda **kw: pytest.fail("bench scale ran without clarabel"))
    code, out, err = run(["bench", "scale", "--quick"], capsys)
    assert code == EXIT_BAD_INPUT and out == ""
    assert err.splitlines()[-1] == 'admmkit: error: bench scale needs clarabel: pip install "clarabel>=0.6"'
