"""What an output path names decides how it is written (issue #46 item 1; docs/cli.md, "Output files").

A regular file or a new name is replaced atomically; a symbolic link's target is replaced and the link stays; a
FIFO, a character device and ``-`` receive the content directly and stay what they are; an empty name, a folder,
one file given to two options and a name without the option's extension are refused before any work.
"""
import json
import os
import socket
import stat
import threading
from contextlib import contextmanager

import pytest

import admmkit.io as aio
from admmkit.cli import main
from admmkit.figures import pyplot, save_figure

QP = ["solve", "qp", "--random", "20", "12", "-q"]
OBSTACLE = ["solve", "obstacle", "--scene", "radial", "--h", "1/8", "--rho", "1", "-q"]
ADAPTIVE = ["solve", "obstacle", "--target-error", "0.1", "-q"]


def run(argv, capsys):
    """(exit code, stdout, stderr) of ``admmkit ARGV``."""
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def refused(argv, capsys, *needles):
    """``argv`` ends with exit 2, one line on stderr holding every needle, and nothing on stdout (nothing run)."""
    code, out, err = run(argv, capsys)
    assert code == 2 and out == "" and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1 and err.startswith("admmkit: error: ")
    for needle in needles:
        assert needle in err, err
    return err


@contextmanager
def fifo_reader(path):
    """A FIFO at ``path`` with a reader thread; yields a list that holds the bytes read once the writer closed."""
    os.mkfifo(path)
    got = []
    reader = threading.Thread(target=lambda: got.append(open(path, "rb").read()), daemon=True)
    reader.start()
    try:
        yield got
    finally:
        reader.join(20)
        if reader.is_alive():                                # nothing wrote: release the reader
            os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
            reader.join(5)


def json_in(text: str) -> dict:
    """The JSON object printed on stdout among the summary lines."""
    lines = text.splitlines()
    start, end = lines.index("{"), lines.index("}")
    return json.loads("\n".join(lines[start:end + 1]))


# ---------------------------------------------------------------- a symbolic link: its target replaced, the link kept
def test_a_symlink_stays_a_link_and_its_target_gets_the_content(tmp_path, capsys):
    target, link = tmp_path / "real.json", tmp_path / "link.json"
    target.write_text("old")
    link.symlink_to(target.name)
    code, out, _ = run([*QP, "--json", str(link)], capsys)
    assert code == 0 and f"json         {link}" in out
    assert link.is_symlink() and os.readlink(link) == "real.json"
    assert json.loads(target.read_text())["result"]["status"] == "converged"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "real.json"]       # no temporary left


def test_a_dangling_symlink_gets_its_target_made(tmp_path, capsys):
    link = tmp_path / "link.csv"
    link.symlink_to("made.csv")
    assert run([*QP, "--csv", str(link)], capsys)[0] == 0
    assert link.is_symlink() and (tmp_path / "made.csv").read_text().startswith("kind,index,x")


def test_a_failing_writer_leaves_the_symlink_and_its_target_as_they_were(tmp_path, monkeypatch):
    target, link = tmp_path / "real.txt", tmp_path / "link.txt"
    target.write_text("old")
    link.symlink_to(target)
    with pytest.raises(RuntimeError):
        with aio.atomic_open(link) as fh:
            fh.write("half")
            raise RuntimeError("the writer fails halfway")

    def full_disk(src, dst):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(aio.os, "replace", full_disk)
    with pytest.raises(OSError, match="No space left"):
        aio.write_text(link, "new")
    assert link.is_symlink() and target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.txt", "real.txt"]


def test_a_symlink_loop_is_refused(tmp_path, capsys):
    loop = tmp_path / "loop.json"
    loop.symlink_to(loop.name)
    refused([*QP, "--json", str(loop)], capsys, "--json", "symbolic link")


# ---------------------------------------------------------------- streams: written directly, never renamed over
def test_a_fifo_gets_the_content_and_stays_a_fifo(tmp_path, capsys):
    fifo = tmp_path / "pipe"
    with fifo_reader(fifo) as got:
        code, out, _ = run([*QP, "--json", str(fifo)], capsys)
    assert code == 0 and f"json         {fifo}" in out
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert json.loads(got[0])["result"]["status"] == "converged"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]


def test_a_fifo_takes_a_plot_and_a_vtu_under_any_name(tmp_path, capsys):
    """The extension rule is for file names: a FIFO gets the flag's format (PNG, VTU), and keeps its name."""
    for flag, magic in (("--plot", b"\x89PNG"), ("--vtk", b"<?xml")):
        fifo = tmp_path / f"pipe{flag}"
        with fifo_reader(fifo) as got:
            code, _, _ = run([*OBSTACLE, flag, str(fifo)], capsys)
        assert code == 0 and got[0].startswith(magic) and stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe--plot", "pipe--vtk"]       # no pipe.png, pipe.vtu


def test_dash_writes_to_standard_output(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run([*QP, "--json", "-"], capsys)
    assert code == 0 and json.loads(out)["result"]["status"] == "converged"          # stdout: the JSON alone
    assert err.rstrip().endswith("json         -") and list(tmp_path.iterdir()) == []    # no file named '-'


def test_a_figure_in_one_format_goes_into_a_stream(tmp_path):
    fig = pyplot().figure()
    with pytest.raises(ValueError, match="one format"):
        save_figure(fig, "-", ("png", "svg"))
    fifo = tmp_path / "fig"
    with fifo_reader(fifo) as got:
        assert save_figure(fig, fifo, ("svg",)) == [fifo]
    assert b"<svg" in got[0] and stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_dev_null_is_written_and_stays_a_device(capsys):
    null = "/dev/null"
    if not stat.S_ISCHR(os.stat(null).st_mode):
        pytest.skip("/dev/null is not a character device here")
    assert aio.target_kind(null) == "stream"                   # (so that the write below never renames over it)
    assert run([*QP, "--json", null], capsys)[0] == 0
    assert stat.S_ISCHR(os.lstat(null).st_mode) and os.major(os.stat(null).st_rdev) == 1


def test_a_socket_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)                                 # (a short path: unix socket names are short)
    with socket.socket(socket.AF_UNIX) as sock:
        sock.bind("sock")
        refused([*QP, "--json", "sock"], capsys, "--json 'sock'", "socket")
        assert stat.S_ISSOCK(os.lstat("sock").st_mode)


# ---------------------------------------------------------------- refused at the entry: exit 2, one line, nothing run
@pytest.mark.parametrize("argv", [QP, ADAPTIVE])
def test_one_file_given_to_two_options_is_refused(argv, tmp_path, capsys):
    same = tmp_path / "same.out"
    err = refused([*argv, "--json", str(same), "--csv", str(same)], capsys, "--json and --csv name the same file")
    assert "give each output its own file" in err and not same.exists()


def test_one_file_through_a_symlink_is_the_same_file(tmp_path, capsys):
    target, link = tmp_path / "r.json", tmp_path / "link"
    link.symlink_to(target)
    refused([*QP, "--history", str(link), "--json", str(target)], capsys,
            f"--history '{link}' and --json '{target}' name the same file")
    refused([*QP, "--json", "-", "--csv", "-"], capsys, "--json and --csv name the same file '-'")
    assert not target.exists()


@pytest.mark.parametrize("argv, flag", [(QP, "--json"), (QP, "--history"), (ADAPTIVE, "--json"),
                                        (OBSTACLE, "--csv"), (OBSTACLE, "--vtk"), (OBSTACLE, "--plot")])
def test_an_empty_name_is_refused(argv, flag, capsys):
    refused([*argv, flag, ""], capsys, f"{flag}: the file name is empty")


def test_a_folder_is_refused(tmp_path, capsys):
    refused([*QP, "--json", str(tmp_path)], capsys, "--json", "is a directory")


@pytest.mark.parametrize("flag, name, ending", [("--vtk", "u.txt", ".vtu"), ("--plot", "u.txt", ".png"),
                                                 ("--vtk", "u", ".vtu"), ("--plot", "u.svg", ".png")])
def test_a_name_without_the_format_s_extension_is_refused(flag, name, ending, tmp_path, capsys, monkeypatch):
    """Never written under another name (``--vtk u.txt`` once wrote ``u.txt.vtu``, ``--plot u.txt`` ``u.png``)."""
    monkeypatch.chdir(tmp_path)
    refused([*OBSTACLE, flag, name], capsys, f"{flag} '{name}'", f"ending in {ending}")
    assert list(tmp_path.iterdir()) == []


def test_the_extension_in_capitals_is_written_under_the_name_given(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert run([*OBSTACLE, "--plot", "U.PNG", "--vtk", "U.VTU"], capsys)[0] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["U.PNG", "U.VTU"]


@pytest.mark.parametrize("name, needle", [("-", "give FILE or FILE.vtu"), ("lv.txt", "give FILE or FILE.vtu")])
def test_target_error_vtk_is_a_base_name(name, needle, tmp_path, capsys, monkeypatch):
    """With --target-error --vtk names FILE_level<k>.vtu (docs/obstacle.md): a stream or another extension is refused."""
    monkeypatch.chdir(tmp_path)
    refused([*ADAPTIVE, "--vtk", name], capsys, f"--vtk '{name}'", needle)
    assert list(tmp_path.iterdir()) == []


def test_a_folder_gone_before_the_write_is_named(tmp_path):
    """The temporary file cannot be made: the error names the file asked for, not the temporary one."""
    target = tmp_path / "gone" / "r.json"
    with pytest.raises(OSError, match=f"could not write {target}"):
        aio.write_text(target, "{}")
