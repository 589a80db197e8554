"""The loops the framework's overhead is measured against: the bare updates, and hand-written loops of the same algorithm (the updates plus exactly the norms the stopping rule and the policy read)."""
from __future__ import annotations

import math
import time
import numpy as np


def bare(problem, rho: float, iterations: int) -> float:
    """Seconds for ``iterations`` of order zx with the problem's own steps, no bookkeeping."""
    x, z, lam = (np.array(v) for v in problem.initial_point())
    Ax = problem.apply_A(x)
    start = time.perf_counter()
    for _ in range(iterations):
        z = problem.z_step(Ax, lam, rho, z)
        x = problem.x_step(z, lam, rho, x)
        Ax = problem.apply_A(x)
        lam = lam + rho * (Ax - z)
    return time.perf_counter() - start


def inline(problem, rho: float, iterations: int) -> float:
    """The same updates written out in numpy."""
    d, b, g = problem.d, problem.b, problem.g
    x = np.zeros_like(d)
    z, lam = x.copy(), x.copy()
    start = time.perf_counter()
    for _ in range(iterations):
        z = np.minimum(g, x + lam / rho)
        x = (b - lam + rho * z) / (d + rho)
        lam = lam + rho * (x - z)
    return time.perf_counter() - start


# -- the hand-written algorithms: the same updates plus exactly the numbers each configuration's
# stopping rule and policy read, computed inline (the norms a rule reads are part of the algorithm) --
def _norm(y) -> float:
    return math.sqrt(np.dot(y, y))


def hand_residual(problem, rho: float, max_iter: int, check_every: int, eps_abs: float = 1e-300,
                  eps_rel: float = 1e-300):
    """Fixed rho, order zx, Boyd's test (3.12) every ``check_every`` iterations and at the last one, by hand.

    On a test iteration: ||r||, ||Ax||, ||z||, ||lam|| and, only when the primal test passes (as the rule
    reads it), rho ||Ax - Ax_prev||; r's memory then takes lam^{k+1} (no array kept for r).
    Returns (seconds, iterations, x).
    """
    x, z, lam = (np.array(v) for v in problem.initial_point())
    Ax = problem.apply_A(x)
    unit = math.sqrt(max(np.dot(np.ones_like(z), np.ones_like(z)), 0.0))    # ||1||: primal and dual unit (zx)
    z_step, x_step, apply_A = problem.z_step, problem.x_step, problem.apply_A
    norm, last = _norm, max_iter - 1
    start = time.perf_counter()
    for k in range(max_iter):
        z = z_step(Ax, lam, rho, z)                                          # (11)
        x = x_step(z, lam, rho, x)                                           # (12)
        if (k + 1) % check_every and k != last:
            Ax = apply_A(x)
            lam = lam + rho * (Ax - z)                                       # (13)
            continue
        Ax_new = apply_A(x)
        r = Ax_new - z
        primal = norm(r)
        r *= rho
        r += lam
        lam, r = r, None                                                     # (13) in r's memory
        eps_pri = unit * eps_abs + eps_rel * max(norm(Ax_new), norm(z), 0.0)
        eps_dual = unit * eps_abs + eps_rel * norm(lam)
        if not math.isfinite(primal):
            break                                                            # diverged
        if primal <= eps_pri and rho * norm(Ax_new - Ax) <= eps_dual:
            Ax = Ax_new
            break
        Ax = Ax_new
    return time.perf_counter() - start, k + 1, x


def hand_sadmm(problem, rho: float, max_iter: int, check_every: int, tol: float = 1e-300,
               tau: float = 2.0, c_max: int = 100):
    """The paper's SADMM by hand: order zx, the summable rule (policies/summable.py) on
    w_k = ||lam^{k+1} - lam^k|| / (rho_k ||A x^{k+1} - A x^k||) every iteration, the relative change
    ||x - x_prev|| <= tol ||x|| tested every ``check_every`` iterations and at the last one (x_prev kept
    only then); lam^{k+1} is written into r's memory once ||r|| is taken.  Returns (seconds, iterations,
    x, final rho)."""
    x, z, lam = (np.array(v) for v in problem.initial_point())
    Ax = problem.apply_A(x)
    z_step, x_step, apply_A = problem.z_step, problem.x_step, problem.apply_A
    norm, last, isnan = _norm, max_iter - 1, math.isnan
    band_low, band_high, changes = 1.0 / (1.0 + tau), 1.0 + tau, 0
    start = time.perf_counter()
    for k in range(max_iter):
        z = z_step(Ax, lam, rho, z)                                          # (14)
        check = not (k + 1) % check_every or k == last
        x_prev = x if check else None
        x = x_step(z, lam, rho, x)                                           # (15)
        Ax_new = apply_A(x)
        r = Ax_new - z
        lam_change = rho * norm(r)                                           # ||lam^{k+1} - lam^k|| = rho ||r||
        r *= rho
        r += lam
        lam, r = r, None                                                     # (16) in r's memory
        Ax_change = rho * norm(Ax_new - Ax)
        Ax = Ax_new
        if check:
            x_change, x_norm = norm(x - x_prev), norm(x)
            if not (math.isfinite(x_change) and math.isfinite(lam_change) and math.isfinite(Ax_change)):
                break                                                        # diverged
            if x_change <= tol * x_norm:
                break
        if Ax_change > 0:                                                    # w_k
            w = lam_change / Ax_change
        else:
            w = math.inf if lam_change > 0 else math.nan
        if isnan(w) or band_low <= w <= band_high:
            continue                                                         # c_{k+1} = c_k, s_k = 0
        changes += 1
        s = tau if changes <= c_max else 1.0 / (changes - c_max) ** 2
        rho = rho * (1.0 + s) if w > band_high else rho / (1.0 + s)          # (17)
    return time.perf_counter() - start, k + 1, x, rho
