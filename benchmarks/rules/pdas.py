"""Reference baseline: the primal-dual active set method (PDAS) = semismooth Newton.

Solves the convex QP with linear inequality constraints

    min 1/2 u'Ku - f'u   subject to   B u <= g          (K symmetric positive definite)

whose KKT system is

    K u - f + B' mu = 0,   mu >= 0,   B u <= g,   mu'(g - B u) = 0.

The complementarity conditions are the nonsmooth equation
C(u, mu) = mu - max(0, mu + c (B u - g)) = 0, and a semismooth Newton step on it
is the primal-dual active set step (Hintermueller, Ito & Kunisch 2002, SIAM J.
Optim. 13(3):865-888, Algorithm 1 and Theorem 3.1):

    A_k = { i : mu_i^k + c (B u^k - g)_i > 0 },   I_k = the rest,
    solve   K u + B_A' mu_A = f,   B_A u = g_A,   mu_I = 0,
    stop when A_{k+1} = A_k (then (u, mu) solves the KKT system exactly, up to
    the round-off of the linear solves).

After the first step only one of the two terms in the test is nonzero at each
index, so c only matters for the start; we start from the unconstrained
solution u = K^{-1} f, mu = 0 (A_0 = the violated constraints).  Convergence is
global and monotone for M-matrices (the P1 obstacle problem); for elasticity
(contact) it is local, so a repeated active set ends the run with status
"cycled" instead of looping.  Round-off guard: an index whose test value is
within 1e-13 of its scale keeps its previous state.

This is a *reference baseline* for the benchmarks (``admmkit bench
precision``): the usual non-ADMM choice for contact and obstacle QPs.  Three
ways to solve the Newton system (``method``):

- ``"bounds"``: every row of B has one nonzero, in distinct columns (u >= psi,
  or contact along an axis-parallel P1 boundary): the active constraints fix
  components of u and the rest solves K_FF u_F = f_F - K_FX u_X, one sparse
  Cholesky per step;
- ``"schur"``: few constraints: with C = B K^{-1} B' and d0 = B K^{-1} f (one
  factorisation of K and m solves, or passed in as ``compliance``), a step is
  the dense solve C_AA mu_A = (d0 - g)_A, and u = K^{-1}(f - B'mu) once at the end;
- ``"kkt"``: general: a sparse LU of the saddle-point matrix [[K, B_A'], [B_A, 0]].

``"auto"`` takes "bounds" if it applies, else "schur" for at most 2000 rows,
else "kkt".
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from admmkit.benchmarks.rules.pdas_steps import _BoundsStep, _KKTStep, _SchurStep

METHODS = ("auto", "bounds", "schur", "kkt")
STATUSES = ("converged", "cycled", "max_iter")
#: "auto" uses the dense Schur complement up to this many constraint rows
SCHUR_MAX_ROWS = 2000
#: relative round-off band of the active-set test (an index inside it keeps its state)
ROUND_OFF = 1e-13


@dataclass
class PDASResult:
    """What :func:`pdas` returns.

    ``u`` the solution, ``mu`` the multiplier of B u <= g (a force: K u - f + B'mu = 0),
    ``lam`` = mu / weights (a pressure density when weights are the lumped
    boundary masses; equal to mu without weights), ``active`` the final active
    set, ``status`` one of converged / cycled / max_iter, ``iterations`` the
    Newton steps, ``history`` one dict per step (k, active, changed, time since
    the start including setup), ``iterates`` and ``multipliers`` the u and mu of
    every step when asked for (``keep_iterates``; computed after the clock stopped),
    ``setup_time`` and ``time`` in seconds, ``kkt`` the residuals at the end.
    """

    u: np.ndarray
    mu: np.ndarray
    lam: np.ndarray
    active: np.ndarray
    status: str
    iterations: int
    method: str
    setup_time: float
    time: float
    kkt: dict
    history: list = field(default_factory=list)
    iterates: list = field(default_factory=list)
    multipliers: list = field(default_factory=list)

    @property
    def converged(self) -> bool:
        """True when the active set settled."""
        return self.status == "converged"


def kkt_residuals(K, f, B, g, u, mu) -> dict:
    """KKT residuals of min 1/2 u'Ku - f'u s.t. Bu <= g at (u, mu), infinity norms.

    stationarity ||Ku - f + B'mu|| / max(||f||, ||B'mu||), infeasibility
    max (Bu - g)^+, negative_multiplier max (-mu)^+, complementarity max |mu (g - Bu)|.
    """
    Bu = B @ u
    stat = K @ u - f + B.T @ mu
    scale = max(float(np.abs(f).max(initial=0.0)), float(np.abs(B.T @ mu).max(initial=0.0)), 1e-300)
    return {
        "stationarity": float(np.abs(stat).max(initial=0.0)) / scale,
        "infeasibility": float(np.maximum(Bu - g, 0.0).max(initial=0.0)),
        "negative_multiplier": float(np.maximum(-mu, 0.0).max(initial=0.0)),
        "complementarity": float(np.abs(mu * (g - Bu)).max(initial=0.0)),
    }


def pdas(K, f, B, g, *, weights=None, method: str = "auto", max_iter: int = 100, c: float = 1.0,
         compliance: tuple | None = None, keep_iterates: bool = False, backend: str = "auto") -> PDASResult:
    """Solve min 1/2 u'Ku - f'u s.t. B u <= g by the primal-dual active set method.

    Parameters
    ----------
    K : (n, n) sparse symmetric positive definite.
    f : (n,) load.  B : (m, n) sparse constraint matrix.  g : (m,) bounds.
    weights : optional (m,) positive weights; ``lam = mu / weights`` is returned
        (the lumped boundary mass M_c makes lam the contact pressure).
    method : "auto", "bounds", "schur" or "kkt" (see the module docstring).
    max_iter : Newton steps, >= 1.
    c : the constant of the complementarity function, > 0.
    compliance : optional (C, d0, recover) with C = B K^{-1} B' (dense m x m),
        d0 = B K^{-1} f and recover(mu) = K^{-1}(f - B'mu); forces "schur" and
        skips its setup (e.g. the contact plug-in's boundary Schur complement).
    keep_iterates : keep u and mu of every step (for work-precision curves); the
        Schur variant recovers those u after the run, outside ``time``.
    backend : sparse Cholesky backend of admmkit.linalg.linsolve for K.
    """
    K, f, B, g, weights = _check(K, f, B, g, weights, max_iter, c, method)
    t_start, cpu_start = time.perf_counter(), time.process_time()
    m = B.shape[0]
    selection = _selection(B)
    if compliance is not None:
        method = "schur"
    elif method == "auto":
        method = "bounds" if selection is not None else "schur" if m <= SCHUR_MAX_ROWS else "kkt"
    if method == "bounds" and selection is None:
        raise ValueError("method='bounds' needs a B with exactly one nonzero per row, in distinct columns")

    step = {"bounds": _BoundsStep, "schur": _SchurStep, "kkt": _KKTStep}[method](K, f, B, g, selection,
                                                                               compliance, backend)
    u, Bu = step.unconstrained()
    mu = np.zeros(m)
    active = Bu - g > 0
    setup_time = time.perf_counter() - t_start
    seen = {active.tobytes()}
    history, steps = [], []
    status = "max_iter"
    k = 0
    for k in range(1, max_iter + 1):
        u, Bu, mu = step.solve(active)
        if keep_iterates:
            steps.append((None if u is None else u.copy(), mu.copy()))
        new = _next_active(active, mu, Bu - g, c, g, Bu)
        changed = int(np.count_nonzero(new != active))
        history.append({"k": k, "active": int(active.sum()), "changed": changed,
                        "time": time.perf_counter() - t_start, "cpu": time.process_time() - cpu_start})
        if changed == 0:
            status = "converged"
            break
        key = new.tobytes()
        if key in seen:
            status = "cycled"
            break
        seen.add(key)
        active = new
    u = step.recover(u, mu)
    total = time.perf_counter() - t_start
    # after the clock stopped: the iterates asked for (the Schur steps recover u only now)
    iterates = [step.recover(uk, muk) for uk, muk in steps]
    lam = mu / weights if weights is not None else mu.copy()
    return PDASResult(u=u, mu=mu, lam=lam, active=active, status=status, iterations=k, method=method,
                      setup_time=setup_time, time=total, kkt=kkt_residuals(K, f, B, g, u, mu),
                      history=history, iterates=iterates, multipliers=[muk for _, muk in steps])


def _next_active(active, mu, slack_violation, c, g, Bu):
    """A_{k+1} = {mu + c (Bu - g) > 0}, indices inside the round-off band keep their state."""
    value = mu + c * slack_violation
    scale = np.where(active, ROUND_OFF * max(float(np.abs(mu).max(initial=0.0)), 1e-300),
                     ROUND_OFF * c * max(float(np.abs(g).max(initial=0.0)), float(np.abs(Bu).max(initial=0.0)), 1e-300))
    return (value > scale) | (active & (value >= -scale))


# ---------------------------------------------------------------- input checks
def _selection(B: sp.csr_matrix):
    """(columns, coefficients) if every row of B has one nonzero in distinct columns, else None."""
    B = B.tocsr()
    B.eliminate_zeros()
    if B.shape[0] == 0 or not np.all(np.diff(B.indptr) == 1):
        return None
    cols = B.indices.copy()
    if np.unique(cols).size != cols.size:
        return None
    return cols, B.data.copy()


def _check(K, f, B, g, weights, max_iter, c, method):
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    if not (isinstance(c, (int, float)) and math.isfinite(c) and c > 0):
        raise ValueError(f"c must be a finite number > 0, got {c!r}")
    K = sp.csr_matrix(K, dtype=float)
    n = K.shape[0]
    if K.shape != (n, n):
        raise ValueError(f"K must be square (n x n), got shape {K.shape}")
    f = np.asarray(f, dtype=float).ravel()
    if f.shape != (n,):
        raise ValueError(f"f must have length n = {n} (from K), got shape {f.shape}")
    B = sp.csr_matrix(B, dtype=float)
    if B.ndim != 2 or B.shape[1] != n:
        raise ValueError(f"B must have n = {n} columns (from K), got shape {B.shape}")
    g = np.asarray(g, dtype=float).ravel()
    if g.shape != (B.shape[0],):
        raise ValueError(f"g must have length m = {B.shape[0]} (rows of B), got shape {g.shape}")
    for name, v in (("K", K.data), ("f", f), ("B", B.data), ("g", g)):
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} must be finite")
    if weights is not None:
        weights = np.asarray(weights, dtype=float).ravel()
        if weights.shape != g.shape or not np.all(np.isfinite(weights)) or np.any(weights <= 0):
            raise ValueError(f"weights must be {g.size} finite numbers > 0 (one per row of B)")
    return K, f, B, g, weights


__all__ = ["pdas", "PDASResult", "kkt_residuals", "METHODS"]
