"""The first hour at the command line (issue #47 items 1-5): one-line errors with suggestions, help that lists
what exists, progress without bar frames in a log, a history of complete rows, ``--progress N >= 1``."""
import csv
import io
import json
import re

import pytest

import admmkit
from admmkit.cli import build_parser, main, plain
from admmkit.cli.output import Progress
from admmkit.linalg.sparse_backends import AUTO_ORDER

from tests.cli_run import one_error_line, run

QP = ["solve", "qp", "--random", "20", "12"]


# ---------------------------------------------------------------- 1. errors: one line, a suggestion, exit 2
@pytest.mark.parametrize("argv, needles", [
    (["slove", "qp"], ["'slove' is not a command of admmkit", "did you mean solve?"]),
    (["bench", "precison"], ["'precison' is not a command of admmkit bench", "did you mean precision?"]),
    ([*QP, "--polcy", "sadmm"], ["unknown option --polcy", "did you mean --policy?"]),
    ([*QP, "--max-iters=5"], ["unknown option --max-iters", "did you mean --max-iter?"]),
    (["--verison"], ["unknown option --verison", "did you mean --version?"]),
    (["solve", "contact", "--tangential", "colomb"], ["--tangential", "frictionless, stick, tresca, coulomb",
                                                      "did you mean coulomb?"]),
    (["solve", "obstacle", "--scene", "radiall"], ["--scene", "radial, pyramid", "did you mean radial?"]),
    (["solve", "obstacle", "--backend", "superlux"], ["--backend", "superlu", "did you mean superlu?"]),
    ([*QP, "--policy", "sumable"], ["--policy: unknown name 'sumable'", "did you mean summable?"]),
    (["solve"], ["admmkit solve needs a command: one of"]),
    ([*QP, "--rho", "-1"], ["--rho", "> 0"]),
    ([*QP, "--progress", "0"], ["--progress", "integer >= 1"]),
    ([*QP, "--progress", "-5"], ["--progress", "integer >= 1"]),
    ([*QP, "--history-every-iteration"], ["--history-every-iteration needs --history FILE"]),
])
def test_a_usage_error_is_one_line_with_a_suggestion(argv, needles, capsys):
    code, out, err = run(argv, capsys)
    line = one_error_line(err)
    assert code == 2 and out == ""
    for needle in needles:
        assert needle in line


def test_a_bad_mesh_size_blames_h_with_its_range(capsys):
    code, _, err = run(["solve", "obstacle", "--h", "3"], capsys)       # was: "n must be an integer >= 1 ..."
    line = one_error_line(err)
    assert code == 2 and line.startswith("admmkit: error: --h: ") and "accepted 0 < h <= 2.66667" in line
    code, _, err = run(["solve", "contact", "--h", "2"], capsys)        # was: blamed on --scene, with a path
    line = one_error_line(err)
    assert code == 2 and line.startswith("admmkit: error: --h: ") and "accepted 0 < h <= min(L, H) = 1.0" in line
    assert "--scene" not in line and ".toml" not in line and "site-packages" not in line


def test_scene_errors_tell_a_missing_file_from_an_unknown_name(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(["solve", "contact", "--scene", "my/scene.toml"], capsys)
    assert code == 2 and one_error_line(err) == "admmkit: error: --scene: no such scene file my/scene.toml"
    code, _, err = run(["solve", "contact", "--scene", "ex3"], capsys)
    line = one_error_line(err)
    assert code == 2 and "unknown scene 'ex3'; give one of block3d, block3d_coulomb, ex1, ex1_coulomb, ex1_tresca, ex2" in line
    assert line.endswith("(did you mean ex2?)")


def test_a_broken_scene_file_is_named_by_its_path(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("h = 'x'\n")
    code, _, err = run(["solve", "contact", "--scene", str(bad)], capsys)
    line = one_error_line(err)
    assert code == 2 and line.startswith(f"admmkit: error: --scene {bad}: key 'h'")


def test_a_study_with_its_own_options_gives_one_line_too(capsys):
    code, _, err = run(["bench", "friction", "--qick"], capsys)
    cost, _, err = err.partition("\n")            # its cost, announced before its own parser reads the options
    assert cost.startswith("bench friction: about 90 s")
    line = one_error_line(err)
    assert code == 2 and "unknown option --qick" in line and "did you mean --quick?" in line


def test_help_still_prints_the_usage(capsys):
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["solve", "qp", "--help"])
    assert stop.value.code == 0 and "usage: admmkit solve qp" in capsys.readouterr().out


# ---------------------------------------------------------------- 2. help lists what exists
def help_of(argv, capsys, options_only=True) -> str:
    """The --help text on one line (argparse wraps), by default its options only (not the usage block)."""
    with pytest.raises(SystemExit):
        build_parser().parse_args([*argv, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    return text.split(" options: ", 1)[1] if options_only else text


def test_help_lists_every_scene_rule_and_backend(capsys):
    from admmkit.problems.contact.model.scene import SCENES_DIR
    from admmkit.problems.obstacle.scene import SCENES
    text = help_of(["solve", "contact"], capsys)
    scenes = sorted(p.stem for p in SCENES_DIR.glob("*.toml"))
    assert len(scenes) >= 5
    for name in scenes:
        assert f"{name} (" in text                           # with its dimension and law
    assert "block3d_coulomb (3-D, coulomb)" in text and "block3d (3-D, frictionless)" in text and "ex1 (2-D, frictionless)" in text
    for rule in admmkit.policy_names():
        assert rule in text.split("--policy NAME")[1].split("--order")[0]
    text = help_of(["solve", "obstacle"], capsys)
    for name in SCENES:
        assert name in text.split("--scene")[1].split("--h")[0]
    backends = text.split("--backend NAME")[1].split("--plot")[0]
    for name in ("auto", *AUTO_ORDER, "iterative", "jacobi"):
        assert name in backends
    assert "the run stops balanced (--balance 0.5)" in text  # the obstacle's real default stop, not 1e-5


@pytest.mark.parametrize("argv", [["solve", "qp"], ["solve", "obstacle"], ["solve", "contact"], ["demo"],
                                  ["reproduce"], ["bench", "precision"], ["bench", "scale"], ["bench", "qp"],
                                  ["bench", "friction"], ["bench", "loop-overhead"], ["bench", "executors"]])
def test_every_command_says_its_typical_cost_and_needs_without_markup(argv, capsys):
    if argv[0] == "bench" and argv[1] in ("friction", "loop-overhead"):   # own parsers: their --help exits 0
        code, out, _ = run([*argv, "--help"], capsys)
        assert code == 0
        text = " ".join(out.split())
    else:
        text = help_of(argv, capsys, options_only=False)
    assert re.search(r"typical: [^.]*(s|min|minutes|hours)\b", text) and "needs: " in text
    assert "``" not in text and "**" not in text and "`" not in text


def test_plain_strips_markup():
    assert plain("``admmkit bench x``: **bold**, *it*, `code` and :mod:`admmkit.cli`") == \
        "admmkit bench x: bold, it, code and admmkit.cli"


# ---------------------------------------------------------------- 3. progress in a log: no frames
class Terminal(io.StringIO):
    def isatty(self):
        return True


class Record:
    def __init__(self, k):
        self.k, self.rho = k, 1.0


def test_progress_on_a_non_terminal_writes_plain_lines_and_no_carriage_return(monkeypatch):
    clock = iter(range(0, 1000, 1))                          # one second per iteration
    monkeypatch.setattr("admmkit.cli.output.time.perf_counter", lambda: float(next(clock)))
    log = io.StringIO()
    with Progress(10_000, file=log) as show:                 # the defaults: 2 s delay, a line every 10 s
        for k in range(60):
            show(Record(k))
    text = log.getvalue()
    assert "\r" not in text and "\x1b" not in text
    lines = text.splitlines()
    assert 3 <= len(lines) <= 7 and all(line.startswith("ADMM: iteration ") for line in lines)


def test_progress_on_a_terminal_still_draws_the_bar(monkeypatch):
    clock = iter(range(0, 1000, 1))
    monkeypatch.setattr("admmkit.cli.output.time.perf_counter", lambda: float(next(clock)))
    tty = Terminal()
    with Progress(10_000, file=tty) as show:
        for k in range(20):
            show(Record(k))
    assert "iterations (cap)" in tty.getvalue() and "\r" in tty.getvalue()


# ---------------------------------------------------------------- 4. history: complete rows
def rows_of(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_the_qp_history_has_complete_rows_of_the_tested_iterations(tmp_path, capsys):
    h, j = tmp_path / "h.csv", tmp_path / "r.json"
    code, out, _ = run([*QP, "--eps", "1e-6", "--history", str(h), "--json", str(j), "-q"], capsys)
    n = json.loads(j.read_text())["result"]["iterations"]
    rows = rows_of(h)
    assert code == 0 and [int(r["k"]) for r in rows] == [k for k in range(n) if (k + 1) % 25 == 0 or k == n - 1]
    assert len(rows) >= 2 and not any(v in ("nan", "") for r in rows for v in r.values())
    # the same run without --history: the same iterations and solution (completing records steers nothing)
    code, _, _ = run([*QP, "--eps", "1e-6", "--json", str(tmp_path / "plain.json"), "-q"], capsys)
    plain_run, with_history = json.loads((tmp_path / "plain.json").read_text()), json.loads(j.read_text())
    assert plain_run["result"]["iterations"] == n and plain_run["arrays"]["x"] == with_history["arrays"]["x"]


def test_history_every_iteration_gives_a_complete_row_per_iteration(tmp_path, capsys):
    h = tmp_path / "h.csv"
    code, out, _ = run([*QP, "--eps", "1e-6", "--history", str(h), "--history-every-iteration", "-q"], capsys)
    n = int(next(line for line in out.splitlines() if line.startswith("iterations")).split()[1])
    rows = rows_of(h)
    assert code == 0 and [int(r["k"]) for r in rows] == list(range(n))
    assert not any(v in ("nan", "") for r in rows for v in r.values())


@pytest.mark.parametrize("argv", [[*QP, "--preset", "textbook"], ["solve", "obstacle", "--h", "1/8"]])
def test_the_plain_loop_history_is_complete_at_every_iteration(argv, tmp_path, capsys):
    h = tmp_path / "h.csv"
    code, out, _ = run([*argv, "--history", str(h), "-q"], capsys)
    n = int(next(line for line in out.splitlines() if line.startswith("iterations")).split()[1])
    rows = rows_of(h)
    assert [int(r["k"]) for r in rows] == list(range(n))
    assert not any(v in ("nan", "") for r in rows for v in r.values())


def test_history_to_csv_rows_all_keeps_every_iteration(scalar_problem, tmp_path):
    result = admmkit.solve(scalar_problem, max_iter=30)
    everything = rows_of(result.history.to_csv(tmp_path / "all.csv"))
    complete = rows_of(result.history.to_csv(tmp_path / "c.csv", rows="complete"))
    assert len(everything) == result.iterations and 1 <= len(complete) <= len(everything)
    assert complete[-1]["k"] == everything[-1]["k"]          # the last row is always complete
    with pytest.raises(ValueError, match="rows must be"):
        result.history.to_csv(tmp_path / "x.csv", rows="some")
