"""Solution polishing: OSQP's active-set refinement (Stellato et al. 2020, section 4; osqp ``src/polish.c``).

From the ADMM iterate (x, z, y) of the problem the loop iterates on (scaled
when the QP is), guess the active constraints

    lower active:  z_i - l_i < -y_i,        upper active:  u_i - z_i < y_i   (the others inactive, y_i = 0),

and solve the equality-constrained QP on them, regularised by delta,

    [P + delta I   A_act'  ] [x    ]   [ -q    ]
    [A_act        -delta I ] [y_act] = [ b_act ],                                   (P1)

b_act the active bounds, followed by ``refine`` steps of iterative
refinement against the unregularised matrix [[P, A_act'], [A_act, 0]].
The regularised matrix is quasi-definite, so it has an LDL' factorisation
in any symmetric order: qdldl's, with its AMD order, as OSQP's polish
(``_reduced_solver``; SuperLU with a symmetric minimum-degree order and no
pivoting where qdldl is not installed).  SuperLU's defaults (COLAMD,
partial pivoting) filled the factor 3-8x and took 3-8x longer on
QSCSD1 or CVXQP3_M: a polishing try during the run (admmkit's preset) cost
as much as 500 iterations.
Then z = clip(A x, l, u).  The polished (x, y) is taken only when the neutral
criteria (:func:`admmkit.problems.qp.residuals.neutral_residuals`: primal, dual, gap)
are better at it than at the unpolished point: polishing never replaces a
better answer.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .problem import QP
from .residuals import neutral_residuals


#: factorise (P1) by the QP's kernels where the process runs its compiled code (False: qdldl's wrapper always)
COMPILED_FACTOR = True


def _worst(res: dict) -> float:
    return max(res["primal"], res["dual"], res["gap"])


def _reduced_solver(K: sp.csc_matrix):
    """``solve(b)`` with K^-1, K the regularised (quasi-definite) matrix of (P1): qdldl's LDL' when installed, else
    SuperLU in symmetric mode (minimum degree on K + K', no pivoting).  Where this process runs the QP's compiled
    code already, qdldl's factor is made by the QP's own kernels (:class:`admmkit.problems.qp.kkt_factor.KKTFactor`:
    AMD's compiled port and qdldl's phases, the same factor and solve bit for bit, 1.4-3.5x faster to order than
    qdldl's wheel, which builds AMD without optimisation)."""
    try:
        import qdldl
    except ImportError:
        lu = spla.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        return lu.solve
    upper = sp.triu(K, format="csc")
    from .segment import kernels_loaded
    if COMPILED_FACTOR and kernels_loaded():
        from .kkt_factor import KKTFactor
        factor = KKTFactor(lambda rho: upper)
        factor.prepare(1.0)
        return lambda b: factor.solve(1.0, b)
    return qdldl.Solver(upper, upper=True).solve


def polish(qp: QP, xb: np.ndarray, zb: np.ndarray, yb: np.ndarray, delta: float = 1e-6, refine: int = 3):
    """Polish the loop's iterate (xb, zb, yb = M lam); return (x, y, info) in the user's problem or (None, None, info).

    ``info``: ``status`` "succeeded" (the polished point is better under the neutral criteria) or "failed",
    the active-set sizes, and the neutral residuals before and after.
    """
    P, q, A, l, u = qp.Ps, qp.qs, qp.As, qp.ls, qp.us
    low = zb - l < -yb
    upp = ~low & (u - zb < yb)
    act = np.flatnonzero(low | upp)
    A_act = sp.csr_matrix(A)[act]
    b_act = np.where(low[act], l[act], u[act])
    n, k = qp.n, act.size
    K0 = sp.bmat([[P, A_act.T], [A_act, None]], format="csc") if k else sp.csc_matrix(P)
    reg = sp.diags(np.r_[np.full(n, delta), np.full(k, -delta)], format="csc")
    rhs = np.r_[-q, b_act]
    info = {"status": "failed", "lower_active": int(low.sum()), "upper_active": int(upp.sum())}
    try:
        solve = _reduced_solver((K0 + reg).tocsc())
        sol = solve(rhs)
        for _ in range(refine):                                   # iterative refinement against K0
            sol = sol + solve(rhs - K0 @ sol)
    except (RuntimeError, ValueError) as err:
        info["reason"] = f"the reduced KKT system could not be solved: {err}"
        return None, None, info
    if not np.all(np.isfinite(sol)):
        info["reason"] = "the reduced KKT solve gave non-finite values"
        return None, None, info
    y_full = np.zeros(qp.m)
    y_full[act] = sol[n:]
    x_pol = qp.finalize(sol[:n])
    y_pol = qp.scaling.unscale_y(y_full) if qp.scaled else y_full
    x0, _, y0 = qp.unscaled(xb, zb, yb if qp.w is None else yb / qp.w)
    before, after = neutral_residuals(qp, x0, y0), neutral_residuals(qp, x_pol, y_pol)
    info.update(before=before, after=after)
    if _worst(after) < _worst(before):
        info["status"] = "succeeded"
        return x_pol, y_pol, info
    info["reason"] = f"not better: worst neutral residual {_worst(after):.3g} polished vs {_worst(before):.3g}"
    return None, None, info
