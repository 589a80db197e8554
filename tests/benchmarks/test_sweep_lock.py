"""One run per output folder (#27 item 3): a live holder makes a second run refuse; a dead one's lock is taken."""
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from admmkit.benchmarks.runner.lock import LOCK_NAME, FolderLocked, hold
from admmkit.benchmarks.runner.sweep import run_sweep
from admmkit.cli import main

FUNC = "test_sweep_faults:fault_case"


def write_lock(folder, pid, host=None):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / LOCK_NAME).write_text(f"{pid} {host or socket.gethostname()} 2026-11-25 00:00:00")


def test_a_second_run_on_a_held_folder_refuses_naming_the_holder(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        write_lock(tmp_path, holder.pid)
        with pytest.raises(FolderLocked, match=f"process {holder.pid}"):
            run_sweep([{"value": 1}], FUNC, tmp_path / "results.jsonl", workers=1, progress=False)
        assert not (tmp_path / "results.jsonl").exists()             # nothing ran
    finally:
        holder.kill()
        holder.wait()


def test_the_lock_of_a_killed_run_is_taken_over_and_released(tmp_path):
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()                                                       # its pid names no process now
    write_lock(tmp_path, gone.pid)
    records = run_sweep([{"value": v} for v in range(3)], FUNC, tmp_path / "results.jsonl", workers=1, progress=False,
                        table=False)
    assert sorted(r["result"]["square"] for r in records.values()) == [0, 1, 4]
    assert not (tmp_path / LOCK_NAME).exists()


def test_a_lock_from_another_machine_is_respected_with_a_way_out(tmp_path):
    write_lock(tmp_path, 12345, host="elsewhere")
    with pytest.raises(FolderLocked, match="delete"):
        with hold(tmp_path):
            pass


def test_two_runs_started_together_run_each_case_once(tmp_path):
    """The second of two concurrent sweeps (two processes) on one folder refuses while the first runs."""
    here = Path(__file__).parent
    code = (f"import sys; sys.path.insert(0, {str(here)!r}); from admmkit.benchmarks.runner.sweep import run_sweep; "
            f"run_sweep([{{'value': v, 'pause': 0.5}} for v in range(4)], {FUNC!r}, {str(tmp_path / 'results.jsonl')!r}, "
            f"workers=1, progress=False, table=False)")
    first = subprocess.Popen([sys.executable, "-c", code], cwd=here.parents[1])
    for _ in range(200):                     # until the first run holds the folder
        if (tmp_path / LOCK_NAME).exists():
            break
        time.sleep(0.05)
    with pytest.raises(FolderLocked, match=f"process {first.pid}"):
        run_sweep([{"value": v, "pause": 0.5} for v in range(4)], FUNC, tmp_path / "results.jsonl", workers=1,
                  progress=False, table=False)
    assert first.wait(timeout=120) == 0
    assert len((tmp_path / "results.jsonl").read_text().splitlines()) == 4


def test_the_command_line_refuses_in_one_line_with_exit_2(tmp_path, capsys):
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        write_lock(tmp_path, holder.pid)
        code = main(["bench", "policies", "--quick", "--out", str(tmp_path), "-q"])
    finally:
        holder.kill()
        holder.wait()
    cost, *err = capsys.readouterr().err.strip().splitlines()
    assert cost.startswith("bench policies: minutes")          # announced before the sweep took its lock
    assert code == 2 and len(err) == 1 and str(holder.pid) in err[0]


@pytest.mark.parametrize("content", [b"", b"garbage", b"12 only-two-fields", b"\xff\xfe not text"])
def test_an_empty_or_garbage_lock_is_taken_over_with_a_note(tmp_path, content, capsys):
    """No run leaves such a lock while it lives (it writes its own at once): it is stale, not 'changing'."""
    lock = tmp_path / LOCK_NAME
    lock.write_bytes(content)
    os.utime(lock, (time.time() - 60, time.time() - 60))             # written a minute ago
    records = run_sweep([{"value": 2}], FUNC, tmp_path / "results.jsonl", workers=1, progress=False, table=False)
    assert [r["result"]["square"] for r in records.values()] == [4]
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"admmkit: note: {lock} was empty or unreadable (no run writes such a lock); taken over"]
    assert not lock.exists()


def test_a_lock_being_written_is_waited_for_then_judged(tmp_path):
    """A fresh empty lock may be a run's between its create and its write: looked at again, then taken."""
    lock = tmp_path / LOCK_NAME
    lock.write_bytes(b"")
    t0 = time.perf_counter()
    with hold(tmp_path):
        assert _holder_pid(lock) == os.getpid()
    assert 0.5 < time.perf_counter() - t0 < 5


def _holder_pid(lock):
    return int(lock.read_text().split()[0])

