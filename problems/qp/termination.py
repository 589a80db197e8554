"""OSQP's termination test for the QP plug-in, at one or several accuracies in one run.

OSQP (Stellato et al. 2020, section 3.4) declares a QP solved at (x, z, y) when

    ||A x - z||_inf         <= eps_abs + eps_rel max(||A x||_inf, ||z||_inf)
    ||P x + q + A'y||_inf   <= eps_abs + eps_rel max(||P x||_inf, ||A'y||_inf, ||q||_inf)

with z in [l, u] and y in the normal cone of [l, u] at z.  In admmkit, z is
the last z-step's output and y the multiplier of that z-step's optimality
condition, ``IterationRecord.lam_z``: lam^{k+1} for order "xz", and for order
"zx" (z-step first) lam^{k+1} - rho (A x^{k+1} - A x^k).  (For order "zx"
the x-step comes last, so P x + q + A' lam^{k+1} is zero up to the proximal
term: testing lam^{k+1} would ignore the sign conditions on y.)

:class:`OSQPTermination` fires at the tightest accuracy and remembers the
first iteration and time at which each looser accuracy was met.  With a rule
that never looks at the clock, the iterates do not depend on the stopping
rule, so one run to 1e-6 also gives the result of a run to 1e-3.
"""
from __future__ import annotations

import math
import time

import numpy as np

from admmkit import IterationRecord, StoppingRule

from .problem import QP


def _inf(v: np.ndarray) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def osqp_residuals(qp: QP, x: np.ndarray, z: np.ndarray, y: np.ndarray, Ax: np.ndarray | None = None) -> dict:
    """OSQP's primal and dual residuals (inf-norms) and the norms its relative tolerances scale with."""
    Ax = qp.A @ x if Ax is None else Ax
    Px = qp.P @ x
    Aty = qp.At @ y
    return {
        "primal": _inf(Ax - z), "primal_scale": max(_inf(Ax), _inf(z)),
        "dual": _inf(Px + qp.q + Aty), "dual_scale": max(_inf(Px), _inf(Aty), _inf(qp.q)),
    }


def osqp_relative_residuals(qp: QP):
    """A function record -> (r_rel, s_rel) with OSQP's normalisation, for ``policies.OSQPRule(residuals=...)``.

    As OSQP's ``compute_rho_estimate``: ||A x - z||_inf / (max(||A x||_inf, ||z||_inf) + 1e-10) and
    ||P x + q + A'y||_inf / (max(||P x||_inf, ||A'y||_inf, ||q||_inf) + 1e-10), with y = ``rec.lam_z``.
    """
    def relative(rec: IterationRecord) -> tuple[float, float]:
        res = osqp_residuals(qp, rec.x, rec.z, rec.lam_z, rec.Ax)
        return (res["primal"] / (res["primal_scale"] + 1e-10), res["dual"] / (res["dual_scale"] + 1e-10))
    return relative


def osqp_satisfied(res: dict, eps: float) -> bool:
    """OSQP's test with eps_abs = eps_rel = eps."""
    return (res["primal"] <= eps + eps * res["primal_scale"]
            and res["dual"] <= eps + eps * res["dual_scale"])


class OSQPTermination(StoppingRule):
    """Stop when OSQP's test holds at the tightest of ``eps`` (eps_abs = eps_rel = eps).

    ``met[eps]`` is (iterations, seconds since the rule was created or
    :meth:`start`-ed, the QP's factorisations so far) at the first iteration
    where the test held at eps, or absent; ``last`` holds the residuals of the
    last iteration checked.  ``clock`` measures the seconds (wall time by
    default; the benchmark passes ``time.process_time``).
    """

    def __init__(self, qp: QP, eps=(1e-3, 1e-6), clock=time.perf_counter):
        epss = sorted({float(e) for e in (eps if np.iterable(eps) else [eps])}, reverse=True)
        if not epss or not all(math.isfinite(e) and e > 0 for e in epss):
            raise ValueError(f"eps must be finite numbers > 0, got {eps!r}")
        self.qp = qp
        self.eps = tuple(epss)                 # loosest first
        self.name = f"osqp(eps={self.eps[-1]:g})"
        self.clock = clock
        self.start()

    def start(self) -> None:
        """Clear what was met and restart the clock."""
        self.met: dict[float, tuple[int, float, int]] = {}
        self.last: dict | None = None
        self.t0 = self.clock()

    def fired(self, rec: IterationRecord) -> str | None:
        """Record each accuracy when first met; fire at the tightest."""
        res = osqp_residuals(self.qp, rec.x, rec.z, rec.lam_z, rec.Ax)
        self.last = res
        for eps in self.eps:
            if eps in self.met:
                continue
            if not osqp_satisfied(res, eps):
                break                           # a tighter eps cannot hold either
            self.met[eps] = (rec.k + 1, self.clock() - self.t0,
                             int(self.qp.counters().get("factorizations", 0)))
        return self.name if self.eps[-1] in self.met else None
