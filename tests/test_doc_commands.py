"""Every ``admmkit`` command printed in the README and the docs runs and ends as the docs say.

A command is a line of a Markdown page indented as code and starting with
``admmkit``.  It must exit 0 unless the same line says otherwise with a
trailing comment ``# exits 1: <why>`` (an infeasible problem, an early stop
shown on purpose).  The studies (``bench``, ``reproduce``) take minutes to an
hour: they are parsed (options and values must be accepted) but not run here,
and are reported as skipped with that reason.  The others run in a fresh
folder, with ``../shared`` pointing at the shared data beside the repository.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
LINE = re.compile(r"^ {4}\$? ?(admmkit(?: [^#\n]*)?)(?:#\s*(.*))?$")
STUDIES = ("bench", "reproduce")
#: the synopsis lines of docs/cli.md (placeholders, not commands)
SYNOPSIS = re.compile(r"[|]|\bSTUDY\b|\[options\]")


def documented_commands() -> list[tuple[str, str, str]]:
    """(page:line, command, comment) for every command printed on a page."""
    found = []
    for page in PAGES:
        fenced = False
        for number, text in enumerate(page.read_text().splitlines(), start=1):
            if text.lstrip().startswith("```"):
                fenced = not fenced
                continue
            match = LINE.match(text) if not fenced else None
            if match and not SYNOPSIS.search(match.group(1)):
                found.append((f"{page.relative_to(ROOT)}:{number}", match.group(1).strip(), match.group(2) or ""))
    return found


COMMANDS = documented_commands()


def expected_exit(comment: str) -> int:
    """1 where the docs say so beside the command (``# exits 1: ...``), else 0."""
    match = re.search(r"exits (\d)", comment)
    return int(match.group(1)) if match else 0


def test_the_docs_print_commands():
    assert len(COMMANDS) >= 40
    assert any(c.startswith("admmkit solve qp") for _, c, _ in COMMANDS)


@pytest.mark.parametrize("where,command,comment", COMMANDS, ids=[w for w, _, _ in COMMANDS])
def test_documented_command_parses(where, command, comment):
    from admmkit.cli import build_parser
    args = shlex.split(command)[1:]
    with pytest.raises(SystemExit) if "--help" in args else _nothing():
        build_parser().parse_args(args)


@pytest.mark.study                     # every documented command in a fresh process: minutes (pytest -m study)
@pytest.mark.parametrize("where,command,comment", COMMANDS, ids=[w for w, _, _ in COMMANDS])
def test_documented_command_ends_as_documented(where, command, comment, tmp_path):
    words = shlex.split(command)
    if len(words) > 1 and words[1] in STUDIES and "--help" not in words:
        pytest.skip(f"a study ({' '.join(words[:3])}): minutes to an hour; parsed above, run by its own tests")
    if "../shared" in command and not SHARED.is_dir():
        pytest.skip("needs ../shared/data beside the repository")
    (tmp_path / "work").mkdir()
    if SHARED.is_dir():
        (tmp_path / "shared").symlink_to(SHARED)
    env = dict(os.environ, MPLBACKEND="Agg", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    code = "import sys; from admmkit.cli import main; sys.exit(main(sys.argv[1:]))"
    done = subprocess.run([sys.executable, "-c", code, *words[1:]], cwd=tmp_path / "work", env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == expected_exit(comment), (
        f"{where}: `{command}` exited {done.returncode}, the docs promise {expected_exit(comment)}\n"
        f"{done.stdout[-2000:]}\n{done.stderr[-2000:]}")
    for figures in promised_counts(comment):       # "# ... 22,904 unknowns": the run prints that count
        assert any(re.search(rf"\b{figure}\b", done.stdout) for figure in figures), (
            f"{where}: the docs say {' or '.join(f'{f:,}' for f in figures)} unknowns for `{command}`; the run "
            f"printed\n{done.stdout[-1500:]}")


def promised_counts(comment: str) -> list[tuple[int, ...]]:
    """The unknown counts a command's comment promises (``18,689 unknowns`` -> (18689,)), each with the
    alternative the docs name for other processors (``18,689 unknowns (or 18,485 ...)`` -> (18689, 18485)): an
    adaptive run's meshes follow the round-off of its stopping tests, which OpenBLAS's kernels set (AVX-512 and
    AVX2 give different counts, docs/obstacle.md)."""
    return [tuple(int(m.replace(",", "")) for m in pair if m)
            for pair in re.findall(r"(\d[\d,]*) unknowns(?: \(or (\d[\d,]*))?", comment)]


def test_promised_counts_reads_a_count_and_its_alternative():
    assert promised_counts("# P2 meshes: 22,904 unknowns, a few seconds") == [(22904,)]
    assert promised_counts("# to 0.1 %: 18,689 unknowns (or 18,485 with AVX2), 2 s") == [(18689, 18485)]
    assert promised_counts("# exits 1: on purpose") == []


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
