"""The one writer of every file admmkit writes: whole or not at all, and only where asked.

Every file admmkit writes (a history CSV, a JSON result, a VTU, a report, a
figure) is first written in full to a temporary file.  What happens next
depends on what the target path names (:func:`target_kind`):

- a regular file or a new name: the temporary file, made beside the target,
  is flushed to disk and renamed over it.  A rename within one folder is
  atomic on POSIX and Windows, so a full disk or a kill leaves either the old
  file or the new one, never a fragment;
- a symbolic link: the link is followed (``os.path.realpath``) and its
  target is replaced as above; the link stays a link;
- a FIFO, a character device (``/dev/null``, a terminal) or ``-`` (standard
  output): the finished content is copied into it, opened for writing; a
  stream is never renamed over and never unlinked;
- a folder, a socket, a block device or an empty name: refused
  (:func:`check_writable`, ValueError naming the option).

A name is never changed: what is written goes to the path given (or, for a
symbolic link, to the file it points at).
"""
from __future__ import annotations

import errno
import os
import shutil
import stat
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

#: the output name that means standard output
STDOUT = "-"


def target_kind(path: str | Path) -> str:
    """What ``path`` names as an output, symbolic links followed.

    ``"stdout"`` (the name ``-``), ``"stream"`` (a FIFO or a character
    device), ``"file"`` (a regular file, or a name not yet taken),
    ``"directory"``, ``"loop"`` (a symbolic link that never ends) or
    ``"other"`` (a socket, a block device).
    """
    text = os.fspath(path)
    if text == STDOUT:
        return "stdout"
    try:
        mode = os.stat(text).st_mode
    except OSError as err:
        return "loop" if err.errno == errno.ELOOP else "file"    # a new name (its folder is checked elsewhere)
    if stat.S_ISDIR(mode):
        return "directory"
    if stat.S_ISREG(mode):
        return "file"
    if stat.S_ISFIFO(mode) or stat.S_ISCHR(mode):
        return "stream"
    return "other"


def is_stream(path: str | Path) -> bool:
    """True if ``path`` is ``-``, a FIFO or a character device: written directly, never renamed over."""
    return target_kind(path) in ("stdout", "stream")


def resolved(path: str | Path) -> Path:
    """The file a write to ``path`` changes: symbolic links followed, ``-`` kept as it is."""
    text = os.fspath(path)
    return Path(text) if text == STDOUT else Path(os.path.realpath(text))


def check_writable(path: str | Path, what: str = "output file") -> Path:
    """Return ``path`` as a Path if a file can be written there, else raise ValueError naming ``what``.

    Refused: an empty name, a folder, a socket or block device, a symbolic
    link loop, a missing or read-only folder (of the link's target for a
    symbolic link) and a stream that may not be written.  Called at an entry
    point before any work, so that a bad path costs nothing.
    """
    if os.fspath(path) == "":
        raise ValueError(f"{what}: the file name is empty; give a file name (or - for standard output)")
    path = Path(path)
    kind = target_kind(path)
    if kind == "stdout":
        return path
    if kind == "directory":
        raise ValueError(f"{what} {str(path)!r} is a directory; give a file name")
    if kind == "loop":
        raise ValueError(f"{what} {str(path)!r} is a symbolic link that never ends (a loop); give a file name")
    if kind == "other":
        raise ValueError(f"{what} {str(path)!r} is a socket or a block device; give a file, a FIFO, "
                         f"a character device or - (standard output)")
    if kind == "stream":
        if not os.access(path, os.W_OK):
            raise ValueError(f"{what} {str(path)!r} is not writable")
        return path
    real = resolved(path)
    named = f"{what} {str(path)!r}" + (f" (a link to {str(real)!r})" if path.is_symlink() else "")
    if not real.parent.is_dir():
        raise ValueError(f"{named}: the directory {str(real.parent)!r} does not exist")
    if not os.access(real.parent, os.W_OK):
        raise ValueError(f"{named}: the directory {str(real.parent)!r} is not writable")
    return path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path to write; on success its content goes to ``path`` (see the module).

    For writers that want a file name (``fig.savefig``, ``np.save``, a VTK
    writer).  A regular file (or a symbolic link's target) is replaced by a
    rename; a stream (``-``, a FIFO, a character device) receives the
    finished content.  On an exception the temporary file is removed and
    ``path`` is left as it was.  The temporary name keeps the suffix, so
    writers that pick a format from it still do.
    """
    if os.fspath(path) == "":
        raise ValueError("the file name is empty; give a file name (or - for standard output)")
    kind = target_kind(path)
    if kind in ("directory", "loop", "other"):
        check_writable(path)                       # raises, naming what the path is
    path = Path(path)
    stream = kind in ("stdout", "stream")
    target = path if stream else resolved(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=target.suffix or ".tmp",
                                   dir=None if stream else target.parent)
    except OSError as err:          # a folder gone since the check, or full
        raise named_os_error(err, path) from err
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        if stream:
            _copy_into_stream(tmp, path)
        else:
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
            os.chmod(tmp, 0o644)
            os.replace(tmp, target)
    except OSError as err:          # a full disk, a lost mount: say which file could not be written
        raise named_os_error(err, path) from err
    finally:
        tmp.unlink(missing_ok=True)


def _copy_into_stream(source: Path, path: Path) -> None:
    """Copy the finished file ``source`` into standard output (``-``) or the FIFO or device ``path``."""
    with open(source, "rb") as src:
        if os.fspath(path) == STDOUT:
            sys.stdout.flush()                     # what was printed before comes first
            out = getattr(sys.stdout, "buffer", None)
            if out is None:                        # a text-only stdout (a notebook): text goes through
                sys.stdout.write(src.read().decode("utf-8"))
            else:
                shutil.copyfileobj(src, out)
                out.flush()
            sys.stdout.flush()
            return
        with open(path, "wb") as out:              # a FIFO waits here for its reader
            shutil.copyfileobj(src, out)


def named_os_error(err: OSError, path: str | Path) -> OSError:
    """``err`` with the file named: "could not write PATH: No space left on device" (errno kept)."""
    if str(path) in str(err):
        return err
    return OSError(err.errno, f"could not write {path}: {err.strerror or err}")


@contextmanager
def atomic_open(path: str | Path, mode: str = "w", **kwargs):
    """``open(path, mode)`` whose content reaches ``path`` only when complete (:func:`atomic_path`)."""
    if not any(m in mode for m in "wx"):
        raise ValueError(f"mode must be a write mode ('w', 'wb', 'x'), got {mode!r}")
    with atomic_path(path) as tmp:
        with open(tmp, mode.replace("x", "w"), **kwargs) as fh:
            yield fh


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` whole or not at all (UTF-8) and return the path."""
    path = Path(path)
    with atomic_open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return path
