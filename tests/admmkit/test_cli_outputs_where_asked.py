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

ROOT = Path(__file__).resolve().parents[2]
QP = ["solve", "qp", "--random", "20", "12"]


def run(argv, capsys):
    """(exit code, stdout, stderr) of ``admmkit ARGV``."""
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def one_error_line(err: str) -> str:
    """The single line of an error (and that it is one: no traceback, nothing else)."""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("admmkit: error: ") and "Traceback" not in err
    return lines[0]


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
    from admmkit.cli_adaptive import adaptive_options
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
