"""One run per output folder: a lock file that names the process holding the folder.

Two sweeps on one ``--out`` would both run every case the other has not
finished yet (nothing is lost, the work is doubled).  :func:`hold` takes
``<folder>/.sweep.lock`` for the length of a sweep; a second run finds it and
refuses with one line that names the holder.  A run that was killed leaves
its lock behind, but the lock names a process that no longer exists, so the
next run takes it over; so does a lock file that is empty or unreadable for
more than a second (no run leaves such a file while it lives), with a one-line
note.  A lock from another machine (a shared file system) cannot be checked
and is respected; its line says how to clear it.
"""
from __future__ import annotations

import os
import socket
import sys
import time
from contextlib import contextmanager
from pathlib import Path

LOCK_NAME = ".sweep.lock"
#: seconds after which an empty or unreadable lock file counts as garbage (a run writes its own at once)
WRITE_GRACE = 1.0


class FolderLocked(ValueError):
    """The output folder is held by another run that is still alive."""


def _alive(pid: int) -> bool:
    """Whether a process with this id exists on this machine."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:      # it exists, under another user
        return True
    return True


def _holder(lock: Path) -> tuple[int, str, str] | None:
    """(pid, host, since) written in a lock file, or None if it is unreadable (being written, or garbage)."""
    try:
        pid, host, since = lock.read_text().split(" ", 2)
        return int(pid), host, since.strip()
    except (OSError, ValueError):
        return None


def _settled(lock: Path) -> bool:
    """Whether the lock file was last written more than WRITE_GRACE seconds ago (or is gone).

    A run writes its lock in one short write right after creating it, so a lock that is still empty or
    unreadable after that is garbage (a crash between the two, a file made by hand), not a run's.
    """
    try:
        return time.time() - lock.stat().st_mtime > WRITE_GRACE
    except OSError:
        return True


@contextmanager
def hold(folder: str | Path):
    """Hold ``folder`` for this process while the block runs; FolderLocked if a live run holds it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lock, me, host = folder / LOCK_NAME, os.getpid(), socket.gethostname()
    for _ in range(100):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _holder(lock)
            if holder is None:
                if _settled(lock):           # empty or garbage for a while: no run is writing it
                    print(f"admmkit: note: {lock} was empty or unreadable (no run writes such a lock); "
                          "taken over", file=sys.stderr)
                    lock.unlink(missing_ok=True)
                else:
                    time.sleep(0.05)         # another run is writing it: look again
                continue
            pid, where, since = holder
            if pid == me and where == host:
                yield                        # this process holds it already (a sweep inside a sweep)
                return
            if where != host:
                raise FolderLocked(f"{folder} is in use by process {pid} on {where} since {since}; if that run "
                                   f"is gone, delete {lock}") from None
            if _alive(pid):
                raise FolderLocked(f"{folder} is in use by another run (process {pid}, since {since}): wait for it "
                                   f"to finish or give another --out") from None
            lock.unlink(missing_ok=True)     # its process is gone (killed): take the folder over
            continue
        with os.fdopen(fd, "w") as f:
            f.write(f"{me} {host} {time.strftime('%Y-%m-%d %H:%M:%S')}")
        break
    else:
        raise FolderLocked(f"{folder}: could not take {lock}: other runs keep taking it; if none is running, "
                           f"delete {lock}")
    try:
        yield
    finally:
        if (_holder(lock) or (None,))[0] == me:
            lock.unlink(missing_ok=True)
