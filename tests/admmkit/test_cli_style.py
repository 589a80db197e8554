"""One command-line style (issue #18) and its exit codes and output paths (issue #16), through ``main()``."""
import csv
import io
import json
import os

import numpy as np
import pytest

import admmkit
from admmkit.cli import run as cli_run
import admmkit.cli as cli
from admmkit import Status
from admmkit.cli import main
from admmkit.cli.output import Progress, exit_code

QP = ["solve", "qp", "--random", "20", "12"]
OBSTACLE = ["solve", "obstacle", "--scene", "radial", "--h", "1/8", "--rho", "1"]
CONTACT = ["solve", "contact", "--scene", "ex1", "--h", "1/10"]


def run(argv, capsys):
    """(exit code, stdout, stderr) of ``admmkit ARGV``."""
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


# ---------------------------------------------------------------- exit codes
@pytest.mark.parametrize("status, code", [(Status.CONVERGED, 0), (Status.CONVERGED_INACCURATE, 1), (Status.MAX_ITER, 1),
                                          (Status.DIVERGED, 1), (Status.STALLED, 1), (Status.TIME_LIMIT, 1),
                                          (Status.STOPPED, 1)])
def test_exit_code_of_every_status(status, code, scalar_problem):
    result = admmkit.solve(scalar_problem, max_iter=3)
    result.status = status
    assert exit_code(result) == code


@pytest.mark.parametrize("argv", [QP, OBSTACLE, CONTACT])
def test_converged_exits_0_and_the_cap_exits_1(argv, capsys):
    code, out, _ = run(argv, capsys)
    assert code == 0 and "status       converged  (" in out
    code, out, _ = run([*argv, "--max-iter", "2"], capsys)
    assert code == 1 and "status       max_iter" in out


@pytest.mark.parametrize("argv", [QP, OBSTACLE, CONTACT])
def test_a_diverged_run_exits_1(argv, capsys, monkeypatch):
    real = admmkit.solve

    def diverging(*args, **kwargs):
        result = real(*args, **kwargs)
        result.status = Status.DIVERGED
        return result
    monkeypatch.setattr(cli_run, "solve", diverging)      # solve qp / obstacle (admmkit.cli.run_solve)
    monkeypatch.setattr(admmkit, "solve", diverging)      # solve contact (admmkit.problems.contact.solvers.methods.solve_scene)
    code, out, _ = run(argv, capsys)
    assert code == 1 and "status       diverged" in out


# ---------------------------------------------------------------- bad input: one line, exit 2, nothing written
BAD = [
    (QP + ["--policy", "sadmmm"], "--policy: unknown name 'sadmmm'"),
    (QP + ["--rho", "0"], "--rho"),
    (QP + ["--eps-rel", "1e-3"], "--eps-rel needs --eps-abs"),
    (QP + ["--max-iter", "0"], "--max-iter"),
    (QP + ["--order", "yx"], "--order"),
    (["solve", "qp", "--random", "0", "3"], "--random"),
    (OBSTACLE + ["--policy", "nope"], "--policy: unknown name 'nope'"),
    (CONTACT + ["--policy", "admm3"], "--policy: unknown name 'admm3'"),
    (CONTACT + ["--method", "admm3"], "--policy: unknown name 'admm3'"),
    (CONTACT + ["--scene", "moon"], "--scene"),
]


@pytest.mark.parametrize("argv, needle", BAD)
def test_bad_input_is_one_line_and_exit_2(argv, needle, capsys):
    code, out, err = run(argv, capsys)
    assert code == 2 and needle in err and "Traceback" not in err
    assert "status" not in out                           # refused before any solve


OUTPUTS = [(QP, "--history"), (QP, "--json"), (QP, "--csv"), (OBSTACLE, "--json"), (OBSTACLE, "--csv"),
           (OBSTACLE, "--plot"), (OBSTACLE, "--history"), (CONTACT, "--json"), (CONTACT, "--csv"),
           (CONTACT, "--vtk"), (CONTACT, "--plot"), (CONTACT, "--history")]


@pytest.mark.parametrize("argv, flag", OUTPUTS)
def test_output_into_a_missing_folder(argv, flag, tmp_path, capsys):
    target = tmp_path / "missing" / "out.file"
    code, out, err = run([*argv, flag, str(target)], capsys)
    assert code == 2 and f"admmkit: error: {flag} " in err and "does not exist" in err
    assert len(err.strip().splitlines()) == 1 and out == "" and not target.parent.exists()


@pytest.mark.parametrize("argv, flag", OUTPUTS)
def test_output_onto_a_folder(argv, flag, tmp_path, capsys):
    folder = tmp_path / ("out.vtu" if flag == "--vtk" else "out")
    folder.mkdir()
    code, out, err = run([*argv, flag, str(folder)], capsys)
    assert code == 2 and "is a directory" in err and len(err.strip().splitlines()) == 1 and out == ""


@pytest.mark.parametrize("argv, flag", OUTPUTS[:4] + OUTPUTS[7:10])
def test_output_into_a_read_only_folder(argv, flag, tmp_path, capsys, monkeypatch):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    if os.geteuid() == 0:   # root writes anyway: report the mode bits as a normal user would see them
        real = os.access
        monkeypatch.setattr(os, "access", lambda p, mode: False if os.path.samefile(p, folder) else real(p, mode))
    try:
        code, out, err = run([*argv, flag, str(folder / "f.out")], capsys)
    finally:
        folder.chmod(0o755)
    assert code == 2 and "is not writable" in err and out == "" and not any(folder.iterdir())


def test_bench_out_onto_a_file(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, _, err = run(["bench", "precision", "--out", str(blocker)], capsys)
    assert code == 2 and "--out" in err and "is a file" in err and blocker.read_text() == "x"
    code, _, err = run(["bench", "precision", "--out", str(blocker / "sub")], capsys)
    assert code == 2 and "is a file, not a folder" in err


def test_a_write_that_fails_late_is_one_line_too(tmp_path, capsys, monkeypatch):
    """A disk that fills after the checks: OSError from the writer -> one line, exit 2, no fragment."""
    import admmkit.io as aio
    real = aio.os.replace

    def full_disk(src, dst):
        raise OSError(28, "No space left on device", str(dst))
    monkeypatch.setattr(aio.os, "replace", full_disk)
    target = tmp_path / "r.json"
    code, _, err = run([*QP, "--json", str(target)], capsys)
    monkeypatch.setattr(aio.os, "replace", real)
    assert code == 2 and "No space left on device" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- --policy everywhere, the paper's names too
@pytest.mark.parametrize("argv, expect", [
    (QP + ["--policy", "admm1"], "admm1: order=xz  policy=Fixed()"),
    (QP + ["--policy", "sadmm"], "sadmm: order=zx  policy=Summable(tau=2.0, c_max=100)"),
    (QP + ["--policy", "sadmm", "--order", "xz"], "sadmm: order=xz"),
    (QP + ["--preset", "textbook"], "residual_balancing: order=xz"),
    (QP, "osqp: order=xz"),
    (OBSTACLE + ["--policy", "admm2"], "admm2: order=zx  policy=Fixed()"),
    (CONTACT, "sadmm: order=zx"),
    (CONTACT + ["--policy", "admm1"], "admm1: order=xz  policy=Fixed()"),
    (CONTACT + ["--policy", "residual_balancing"], "residual_balancing: order=zx"),
])
def test_policy_accepts_rules_and_the_paper_methods(argv, expect, capsys):
    code, out, _ = run(argv, capsys)
    assert code in (0, 1) and expect in out
    assert sum(line.startswith("method ") for line in out.splitlines()) == 1     # no line printed twice


def test_method_is_a_deprecated_alias_of_policy(capsys):
    code, out, err = run([*CONTACT, "--method", "sadmm"], capsys)
    assert code == 0 and "sadmm: order=zx" in out and "--method is deprecated; use --policy" in err
    code, out, _ = run([*CONTACT, "--help"], capsys)
    assert code == 0 and "--policy NAME" in out and "--method" not in out


def test_integers_are_printed_as_integers(capsys):
    _, out, _ = run(CONTACT, capsys)
    kkt = next(line for line in out.splitlines() if line.startswith("KKT"))
    active = next(line for line in out.splitlines() if line.startswith("contact "))
    n = int(kkt.split("active_nodes ")[1].split()[0])                   # "21", not "2.100e+01"
    assert f"active nodes {n}/20" in active                             # one definition, one count


# ---------------------------------------------------------------- JSON and CSV for every solve
@pytest.mark.parametrize("argv, arrays, columns", [
    (QP + ["--preset", "textbook"], {"x": 20, "z": 12, "lam": 12},
     ["kind", "index", "x", "z", "lam", "l", "u", "certificate", "status", "termination", "neutral_primal",
      "neutral_dual", "neutral_gap"]),
    (OBSTACLE, {"u": 961, "node_xy": 961, "free_nodes": 961}, ["node", "x", "y", "u", "psi", "in_contact"]),
])
def test_json_and_csv_for_qp_and_obstacle(argv, arrays, columns, tmp_path, capsys):
    j, c = tmp_path / "r.json", tmp_path / "r.csv"
    code, out, _ = run([*argv, "--json", str(j), "--csv", str(c), "--tol", "1e-6"], capsys)
    assert code in (0, 1) and f"json         {j}" in out and f"csv          {c}" in out
    data = json.loads(j.read_text())
    prov = data["provenance"]
    assert prov["admmkit_version"] == admmkit.__version__ and prov["date"].endswith("+00:00")
    assert prov["command_line"].startswith("admmkit solve ") and prov["stopping_rule"] == "relative_change(tol=1e-06)"
    assert data["result"]["status"] in ("converged", "converged_inaccurate")
    assert isinstance(data["result"]["iterations"], int)
    for name, n in arrays.items():
        assert len(data["arrays"][name]) == n
    rows = list(csv.reader(c.open()))
    assert rows[0] == columns and len(rows) == 1 + max(arrays.values()) + (12 if "qp" in argv else 0)


# ---------------------------------------------------------------- progress
def test_progress_lines_every_n_iterations(capsys):
    code, _, err = run([*QP, "--progress", "5"], capsys)
    ks = [int(line.split()[1]) for line in err.splitlines() if line.strip().startswith("iteration")]
    assert code == 0 and ks and all(k % 5 == 0 for k in ks) and ks[0] == 5


def test_progress_bar_after_the_delay_and_quiet_silences_it(capsys, monkeypatch):
    monkeypatch.setattr("admmkit.cli.output.PROGRESS_DELAY", 0.0)
    monkeypatch.setattr("admmkit.cli.output.PROGRESS_INTERVAL", 0.0)
    _, _, err = run(QP, capsys)
    assert "ADMM: iteration" in err and "\r" not in err    # stderr is no terminal here: plain lines, no bar
    _, _, err = run([*QP, "-q"], capsys)
    assert err == ""
    _, _, err = run([*QP, "--quiet", "--progress", "5"], capsys)
    assert err == ""


def test_the_summary_begins_its_own_line_when_stdout_and_stderr_share_a_log(tmp_path):
    """#27 item 5: with ``> log 2>&1`` the bar's last frame must not run into the summary's ``status`` line."""
    import subprocess
    import sys
    script = ("import sys, admmkit.cli.output as o; o.PROGRESS_DELAY = o.PROGRESS_INTERVAL = 0.0; "
              "from admmkit.cli import main; sys.exit(main(sys.argv[1:]))")
    log = tmp_path / "log"
    with open(log, "w") as fh:                             # one file for both streams, as `> log 2>&1`
        subprocess.run([sys.executable, "-c", script, *QP], stdout=fh, stderr=subprocess.STDOUT,
                       cwd=os.getcwd(), check=True, timeout=300)
    text = log.read_text()
    assert "ADMM: iteration" in text and "\r" not in text  # a log gets plain progress lines, never bar frames
    lines = text.split("\n")
    assert any(line.startswith("status") for line in lines), text
    assert not any("\r" in line and "status" in line for line in lines), text


def test_short_runs_show_nothing(capsys):
    _, _, err = run(QP, capsys)
    assert err == ""


def test_the_progress_callback_never_steers(vector_problem):
    class Terminal(io.StringIO):
        def isatty(self):
            return True
    stream = Terminal()
    plain = admmkit.solve(vector_problem, rho=1.0, max_iter=200)
    with Progress(200, delay=0.0, interval=0.0, file=stream) as show:
        shown = admmkit.solve(vector_problem, rho=1.0, max_iter=200, callback=show)
    assert "iterations (cap)" in stream.getvalue()       # on a terminal: tqdm's bar
    assert shown.iterations == plain.iterations and shown.status == plain.status
    assert np.array_equal(shown.x, plain.x) and np.array_equal(shown.lam, plain.lam)
    with Progress(10, enabled=False) as show:
        assert show is None


@pytest.mark.parametrize("argv", [QP, OBSTACLE, CONTACT])
def test_fired_at_the_iteration_count(argv, capsys):
    _, out, _ = run(argv, capsys)
    fired = int(out.split("fired at iteration ")[1].split()[0].rstrip(",)"))
    count = int(next(line for line in out.splitlines() if line.startswith("iterations")).split()[1])
    assert fired == count


def test_a_fraction_is_the_float_fractions_gives():
    """--h 1/40 divides two integers without importing fractions (issue #49): the same float, the same errors."""
    import argparse
    from fractions import Fraction
    from admmkit.cli.options import positive_float
    for text in ("1/40", "1/3", "7/200", "+1/7", " 1/40", "10000000000000000000001/3", "1_0/3"):
        assert positive_float(text) == float(Fraction(text)), text
    for text in ("1/0", "1 / 40", "/3", "1/", "--1/3", "1/-3", "-1/3", "1e3/7", "2/3e0", "0.1/3"):
        with pytest.raises(argparse.ArgumentTypeError):
            positive_float(text)


def test_set_help_keeps_hidden_options_hidden_without_making_lazy_helps():
    """set_help replaces a shown option's help, leaves a hidden one (plain or LazyHelp) hidden, and does not call a
    LazyHelp's text function to find out."""
    import argparse
    from admmkit.cli import LazyHelp, set_help
    made = []
    p = argparse.ArgumentParser()
    p.add_argument("--shown", action=LazyHelp, help=lambda: made.append(1) or "listed")
    p.add_argument("--alias", dest="shown", help=argparse.SUPPRESS)
    p.add_argument("--hidden", action=LazyHelp, help=argparse.SUPPRESS)
    set_help(p, shown="new text", hidden="should stay hidden")
    helps = {a.option_strings[0]: a.help for a in p._actions if a.option_strings and a.option_strings[0] != "-h"}
    assert made == [] and helps == {"--shown": "new text", "--alias": argparse.SUPPRESS, "--hidden": argparse.SUPPRESS}


def test_policy_help_lists_the_rules_whatever_its_words():
    """--policy's help lists the installed rules after "penalty rule or method", or at its end when a sub-command
    words its help otherwise (before: such a help listed nothing, silently)."""
    import argparse
    from admmkit.cli.options import _PolicyOption
    from admmkit.policy import policy_names
    p = argparse.ArgumentParser()
    p.add_argument("--policy", action=_PolicyOption, methods={"sadmm": None}, help="the penalty rule or method (x)")
    p.add_argument("--rule", action=_PolicyOption, help="the rho update")
    helps = {a.dest: a.help for a in p._actions}
    some = policy_names()[0]
    assert helps["policy"].startswith("the penalty rule or method: sadmm, ") and some in helps["policy"]
    assert helps["rule"].startswith("the rho update (one of: ") and some in helps["rule"]
