"""Writing files whole or not at all.

Every file admmkit writes (a history CSV, a JSON result, a VTU, a report, a
figure) goes to a temporary file in the same folder, is flushed to disk and
then renamed over the target.  A rename within one folder is atomic on POSIX
and Windows, so a full disk or a kill leaves either the old file or the new
one, never a fragment.
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator


def check_writable(path: str | Path, what: str = "output file") -> Path:
    """Return ``path`` as a Path if a file can be written there, else raise ValueError naming it.

    The folder must exist and be writable and ``path`` must not be a folder.
    Called at an entry point before any work, so that a bad path costs nothing.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ValueError(f"{what} {str(path)!r} is a directory; give a file name")
    if not folder.is_dir():
        raise ValueError(f"{what} {str(path)!r}: the directory {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"{what} {str(path)!r}: the directory {str(folder)!r} is not writable")
    return path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``.

    For writers that want a file name (``fig.savefig``, ``np.save``, a VTK
    writer).  On an exception the temporary file is removed and ``path`` is
    left as it was.  The temporary name keeps the suffix, so writers that
    pick a format from it still do.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix or ".tmp",
                               dir=path.parent if str(path.parent) else ".")
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except OSError as err:          # a full disk, a lost mount: say which file could not be written
        tmp.unlink(missing_ok=True)
        raise named_os_error(err, path) from err
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def named_os_error(err: OSError, path: str | Path) -> OSError:
    """``err`` with the file named: "could not write PATH: No space left on device" (errno kept)."""
    if str(path) in str(err):
        return err
    return OSError(err.errno, f"could not write {path}: {err.strerror or err}")


@contextmanager
def atomic_open(path: str | Path, mode: str = "w", **kwargs):
    """``open(path, mode)`` that writes a temporary file and renames it into place on success."""
    if not any(m in mode for m in "wx"):
        raise ValueError(f"mode must be a write mode ('w', 'wb', 'x'), got {mode!r}")
    with atomic_path(path) as tmp:
        with open(tmp, mode.replace("x", "w"), **kwargs) as fh:
            yield fh


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically and return the path."""
    path = Path(path)
    with atomic_open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return path
