"""What every scene of ``admmkit bench adaptive`` shares: a level's row, the study's clock, one uniform solve."""
from __future__ import annotations

import math
import time

#: the columns only Hertz fills (the errors in its contact half-width and peak pressure); NaN elsewhere
HERTZ_COLUMNS = ("a_error", "p0_error")


def level_row(scene, order, method, level, h, unknowns, relative_estimate, estimate, true_error, absolute_error,
              iterations, seconds, wall, status, cold_iterations=None, algebraic_error=math.nan, **extra) -> dict:
    """One row of the study (printed as it is made); ``algebraic_error``: ||u - u_h*||_a at the stop (adaptive levels,
    :mod:`admmkit.benchmarks.adaptive.algebraic`); ``extra``: the Hertz columns, if any."""
    row = {"scene": scene, "order": order, "method": method, "level": level, "h": h, "unknowns": unknowns,
           "relative_estimate": relative_estimate, "true_error": true_error,
           "effectivity": estimate / absolute_error if not absolute_error <= 0 else math.inf,   # NaN: error NaN
           "iterations": iterations, "cold_iterations": iterations if cold_iterations is None else cold_iterations,
           "seconds": seconds, "wall_seconds": wall, "status": status,
           "algebraic_over_estimate": algebraic_error / estimate if estimate > 0 else math.nan}
    row |= {key: extra.get(key, math.nan) for key in HERTZ_COLUMNS}
    print(f"  {scene:9s} P{order} {method:14s} {level:2d}  n = {unknowns:7d}  est {relative_estimate:.3e}  "
          f"true {true_error:.3e}  eff {row['effectivity']:.2f}  it {iterations:4d} (cold {row['cold_iterations']:4d})"
          f"  wall {wall:7.2f} s" + (f"  alg/eta {row['algebraic_over_estimate']:.2f}"
                                     if math.isfinite(row["algebraic_over_estimate"]) else ""), flush=True)
    return row


class Clock:
    """Wall time since start, less the time spent in the study's own callbacks (the true error)."""

    def __init__(self):
        self.start, self.excluded = time.perf_counter(), 0.0

    def now(self) -> float:
        """Seconds so far, without the excluded ones."""
        return time.perf_counter() - self.start - self.excluded


def uniform_level(solve_adaptive, scene, measure, **options):
    """One mesh, one level, cold: its Level, the wall time to the level's end, and ``measure(model, result)``.

    Taken in the level's callback: after it the loop refines the mesh, which a uniform solve does not need.
    """
    got, t0 = {}, time.perf_counter()

    def log(level, out):
        got["wall"] = time.perf_counter() - t0
        got["level"], got["value"] = level, measure(out.model, out.result)
    solve_adaptive(scene, 1e-9, max_levels=1, log=log, **options)
    return got["level"], got["wall"], got["value"]
