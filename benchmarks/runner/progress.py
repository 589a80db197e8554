"""The progress line of a sweep: cases done, failures, elapsed time and an estimate of the rest (on stderr)."""
from __future__ import annotations

import sys
import time


def _fmt_seconds(s: float) -> str:
    s = max(0.0, s)
    if s < 60:
        return f"{s:4.0f}s"
    if s < 3600:
        return f"{int(s // 60)}m{int(s % 60):02d}s"
    return f"{int(s // 3600)}h{int((s % 3600) // 60):02d}m"


class Progress:
    """A one-line progress bar on stderr: [#####-----] done/total, elapsed, eta, last case."""

    def __init__(self, total: int, skipped: int, enabled: bool = True, stream=None):
        self.total, self.skipped, self.enabled = total, skipped, enabled
        self.done, self.failed = 0, 0
        self.start = time.perf_counter()
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def update(self, label: str, failed: bool = False) -> None:
        """Count one finished case and redraw the line."""
        self.done += 1
        self.failed += int(failed)
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        todo = self.total - self.skipped
        eta = elapsed / self.done * (todo - self.done) if self.done else float("nan")
        width = 24
        frac = (self.skipped + self.done) / max(self.total, 1)
        bar = "#" * int(round(width * frac)) + "-" * (width - int(round(width * frac)))
        line = (f"[{bar}] {self.skipped + self.done}/{self.total} ({100 * frac:5.1f}%)  "
                f"elapsed {_fmt_seconds(elapsed)}  eta {_fmt_seconds(eta) if self.done else '   ?'}"
                f"{'  failed ' + str(self.failed) if self.failed else ''}  {label[:60]}")
        if self.tty:
            self.stream.write("\r" + line.ljust(150))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        """End the line."""
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()
