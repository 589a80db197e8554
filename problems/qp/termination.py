"""OSQP's termination tests for the QP plug-in: :class:`QPTermination` (OSQP 1.x's, with the duality gap and
infeasibility detection, the QP's default) and :class:`OSQPTermination` (residuals only, several accuracies in one run).

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

from admmkit import IterationRecord, Status, Stop, StoppingRule
from admmkit.kernels import compiled_now, kernel
from admmkit.loop.segments import AVAILABLE as NUMBA

from .infeasibility import DIVISION_TOL, confirmed_certificate, dual_certificate, iterate_deltas, primal_certificate
from .problem import QP
from .residual_kernel import iterate_residuals_compiled
from .residuals import iterate_residuals, osqp_residuals  # noqa: F401  (osqp_residuals: re-exported)
from .sparse_kernels import inf_norms


def _iterate(qp: QP, rec: IterationRecord, scaled: bool = False) -> dict:
    """OSQP's residuals of the user's problem at the record's iterate, with y from ``rec.lam_z`` (and OSQP's
    relaxed x when the QP relaxes x), the scaled ones for the rho estimate too.

    Computed once per record: the policy, the termination test and the result read the same iterate
    every 50 iterations and at the end (the QP keeps the last record's, ``qp._residuals_of``)."""
    kept = qp._residuals_of
    if kept is not None and kept[0] is rec:
        return kept[1]
    x = qp.relaxed_x(rec.x)
    res = _from_kernel(qp, x, rec) if KERNEL_RESIDUALS else None
    if res is None:
        Ax = rec.Ax if x is rec.x and qp.xstep != "kkt" else None      # the KKT form's is z~ (Q6): OSQP takes A x
        res = residuals_of_iterate()(qp, x, rec.z, rec.lam_z, Ax, scaled=True)
    qp._residuals_of = (rec, res)
    return res


#: take the residuals of a read iteration from the segment's kernel that computed them at its end
#: (``segment_checks.go_on``: the same kernel on the same arrays, so the same numbers); False: computed anew
KERNEL_RESIDUALS = True


def _from_kernel(qp: QP, x: np.ndarray, rec: IterationRecord) -> dict | None:
    """The dict ``residual_kernel.iterate_residuals_compiled(..., scaled=True)`` gives at the record's iterate,
    from the 11 numbers the segment's kernel computed on these very arrays (OSQP's x ``x``, z and lam of the
    record, order "xz", the KKT form: A x taken as a product), or None when it did not."""
    held = qp.__dict__.get("_kernel_residuals")
    if held is None or x is not held[0] or rec.order != "xz" or qp.xstep != "kkt":
        return None
    z, lam = rec.z, rec.lam
    if not ((z is held[1] or z.base is held[1]) and (lam is held[2] or lam.base is held[2])):
        return None
    (primal, primal_scale, dual, dual_scale, quad, lin, sup,
     s_primal, s_primal_scale, s_dual, s_dual_scale) = held[3]
    cinv = 1.0 / qp.scaling.c if qp.scaled else 1.0
    return {"primal": primal, "primal_scale": primal_scale, "dual": cinv * dual, "dual_scale": cinv * dual_scale,
            "gap": cinv * (quad + lin + sup), "gap_scale": cinv * max(abs(quad), abs(lin), abs(sup)),
            "scaled_primal": s_primal, "scaled_primal_scale": s_primal_scale, "scaled_dual": s_dual,
            "scaled_dual_scale": s_dual_scale}


def residuals_of_iterate():
    """:func:`iterate_residuals`, compiled in one pass when numba is installed (``residual_kernel``)."""
    if NUMBA:
        return iterate_residuals_compiled
    return iterate_residuals


def osqp_relative_residuals(qp: QP):
    """A function record -> (r_rel, s_rel) with OSQP 1.x's normalisation, for ``policies.OSQPRule(residuals=...)``.

    As OSQP 1.x's ``compute_rho_estimate``, in the problem the loop iterates on (the scaled one when
    ``qp.scaling``): ||A x - z||_inf / (max(||A x||_inf, ||z||_inf) + 1e-30) and
    ||P x + q + A'y||_inf / (max(||P x||_inf, ||A'y||_inf, ||q||_inf) + 1e-30), with y = M ``rec.lam_z``.
    """
    return _RelativeResiduals(qp)


class _RelativeResiduals:
    """The function :func:`osqp_relative_residuals` returns; its repr names it (a run's provenance reads the same
    in every process, without a memory address)."""

    __slots__ = ("qp",)

    def __init__(self, qp: QP) -> None:
        self.qp = qp

    #: the ratios :func:`admmkit.problems.qp.segment_checks.go_on` computes in the segment for OSQPRule
    osqp_ratios = True

    def __call__(self, rec: IterationRecord) -> tuple[float, float]:
        res = _iterate(self.qp, rec, scaled=True)
        return (res["scaled_primal"] / (res["scaled_primal_scale"] + DIVISION_TOL),
                res["scaled_dual"] / (res["scaled_dual_scale"] + DIVISION_TOL))

    def __repr__(self) -> str:
        return "osqp_relative_residuals(qp)"


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
        res = _iterate(self.qp, rec)
        self.last = res
        for eps in self.eps:
            if eps in self.met:
                continue
            if not osqp_satisfied(res, eps):
                break                           # a tighter eps cannot hold either
            self.met[eps] = (rec.k + 1, self.clock() - self.t0,
                             int(self.qp.counters().get("factorizations", 0)))
        return self.name if self.eps[-1] in self.met else None


#: the tests a QPTermination reports as fired
SOLVED, PRIMAL_INFEASIBLE, DUAL_INFEASIBLE = "solved", "primal_infeasible", "dual_infeasible"

#: rows (columns) whose inf-norm is below the largest one's over SCALE_SPAN are out of the tolerance's sight
SCALE_SPAN = 1e10
#: an infeasibility certificate's equations must hold to this fraction of the sizes they sum (ScaleCheck.certifies)
CERTIFICATE_TOL = 1e-6


class ScaleWarning(UserWarning):
    """The QP's scale makes a tolerance vacuous on some rows or columns (``QPResult.warnings`` says which)."""


def _column_norms(M) -> np.ndarray:
    """The inf-norm of every column of the CSC matrix ``M`` (of every row if ``M`` is CSR; an empty one: 0)."""
    out = np.zeros(len(M.indptr) - 1)
    full = np.flatnonzero(np.diff(M.indptr))
    if full.size:
        out[full] = np.maximum.reduceat(np.abs(M.data), M.indptr[full])
    return out


def _row_and_column_norms(M) -> tuple[np.ndarray, np.ndarray]:
    """(the inf-norm of every row, of every column) of the CSC matrix ``M``: one compiled pass where numba is
    chosen (``sparse_kernels.inf_norms``, no CSR copy), else :func:`_column_norms` of M' and of M."""
    if NUMBA and compiled_now():
        return inf_norms(M.indptr, M.indices, M.data, M.shape[0])
    return _column_norms(M.tocsr()), _column_norms(M)


def _indices(idx: np.ndarray, shown: int = 8) -> str:
    """'3, 7, 12' or '0, 1, ..., 29 (30 in all)'."""
    head = ", ".join(str(int(i)) for i in idx[:shown])
    return head if idx.size <= shown else f"{head}, ... ({idx.size} in all)"


@kernel(cache=True)
def scale_facts(Ap, Ai, Ax, Pp, Pi, Px, l, u, span):
    """:class:`ScaleCheck`'s arrays in one pass over A, P, l and u: (nu, live, bound, kappa, span_rows, void_rows,
    span_columns), the numbers its vector form gives (``ScaleCheck(qp)`` with compiled code off)."""
    m, n = l.shape[0], Ap.shape[0] - 1
    nu, kappa = inf_norms(Ap, Ai, Ax, m)            # row and column inf-norms of A ...
    column_p = inf_norms(Pp, Pi, Px, n)[1]          # ... and the larger of A's and P's per column (a max is exact)
    for j in range(n):
        if column_p[j] > kappa[j]:
            kappa[j] = column_p[j]
    live = np.empty(m, np.bool_)
    bound = np.empty(m)
    top = 0.0
    voids = 0
    for i in range(m):
        finite_l, finite_u = np.isfinite(l[i]), np.isfinite(u[i])
        live[i] = (finite_l or finite_u) and nu[i] > 0
        bl = abs(l[i]) if finite_l else 0.0
        bu = abs(u[i]) if finite_u else 0.0
        bound[i] = bu if bu > bl else bl
        if live[i] and nu[i] > top:
            top = nu[i]
        if nu[i] == 0 and (l[i] > 0 or u[i] < 0):
            voids += 1
    top_column = 0.0
    for j in range(n):
        if kappa[j] > top_column:
            top_column = kappa[j]
    row_floor, column_floor = top / span, top_column / span
    spans = 0
    for i in range(m):
        if live[i] and nu[i] < row_floor:
            spans += 1
    span_rows = np.empty(spans, np.int64)
    void_rows = np.empty(voids, np.int64)
    s = v = 0
    for i in range(m):
        if live[i] and nu[i] < row_floor:
            span_rows[s] = i
            s += 1
        if nu[i] == 0 and (l[i] > 0 or u[i] < 0):
            void_rows[v] = i
            v += 1
    columns = 0
    for j in range(n):
        if kappa[j] > 0 and kappa[j] < column_floor:
            columns += 1
    span_columns = np.empty(columns, np.int64)
    c = 0
    for j in range(n):
        if kappa[j] > 0 and kappa[j] < column_floor:
            span_columns[c] = j
            c += 1
    return nu, live, bound, kappa, span_rows, void_rows, span_columns


class ScaleCheck:
    """Which rows and columns of the user's QP a tolerance cannot see (issue #46).

    With nu_i = ||a_i||_inf of a constrained row (a finite bound, a_i != 0):

    - span rows: nu_i < max nu / SCALE_SPAN; the relative tolerance eps_rel max(||Ax||_inf, ||z||_inf)
      is set by the largest rows and passes any residual of these;
    - tiny rows (at an answer x): nu_i max(1, ||x||_inf) and the row's finite bounds all below eps_abs;
      the absolute tolerance alone exceeds every number the row holds, so its test cannot fail.

    On such rows OSQP's (R1) is vacuous; ``row_test`` is its row-normalised form
    (R1') max_i |Ax - z|_i / nu_i <= eps_abs + eps_rel max_i max(|Ax|_i, |z|_i) / nu_i, the same test
    in the problem whose rows have unit norm, unchanged by any row scaling.  Void rows (no entry, bounds
    that exclude 0) make the QP infeasible whatever x is; when their bounds are within eps_abs of 0 the test
    cannot see it, so a solved run with void rows ends ``converged_inaccurate``.  Span columns
    (kappa_j = ||(P; A)_j||_inf below max kappa / SCALE_SPAN) leave the dual test (R2) blind on
    them; no cheap normalised form is taken, so a run with such columns ends ``converged_inaccurate``.
    """

    def __init__(self, qp: QP):
        self.qp = qp
        if NUMBA and compiled_now():        # one compiled pass, the same arrays (a max and a comparison are exact)
            A, P = qp.A, qp.P
            (self.nu, self.live, self.bound, self.kappa, self.span_rows, self.void_rows,
             self.span_columns) = scale_facts(A.indptr, A.indices, A.data, P.indptr, P.indices, P.data,
                                              qp.l, qp.u, SCALE_SPAN)
            return
        nu, col_A = _row_and_column_norms(qp.A)
        finite_l, finite_u = np.isfinite(qp.l), np.isfinite(qp.u)
        self.live = (finite_l | finite_u) & (nu > 0)
        self.nu = nu
        self.bound = np.maximum(np.where(finite_l, np.abs(qp.l), 0.0), np.where(finite_u, np.abs(qp.u), 0.0))
        top = nu[self.live].max(initial=0.0)
        self.span_rows = np.flatnonzero(self.live & (nu < top / SCALE_SPAN))
        self.void_rows = np.flatnonzero((nu == 0) & ((qp.l > 0) | (qp.u < 0)))
        kappa = np.maximum(col_A, _row_and_column_norms(qp.P)[1])
        self.kappa = kappa
        self.span_columns = np.flatnonzero((kappa > 0) & (kappa < kappa.max(initial=0.0) / SCALE_SPAN))

    def tiny_rows(self, x: np.ndarray, eps_abs: float) -> np.ndarray:
        """The constrained rows whose every number (nu_i max(1, ||x||_inf), the finite bounds) is below eps_abs."""
        reach = self.nu * max(1.0, float(np.max(np.abs(x), initial=0.0)))
        return np.flatnonzero(self.live & (reach < eps_abs) & (self.bound < eps_abs))

    def may_be_blind(self, eps_abs: float) -> bool:
        """Whether some x makes a row blind: span rows, or rows that are tiny at x = 0 (nu_i max(1, ||x||_inf) only
        grows with x, so a row not tiny there is tiny nowhere).  Asked once per tolerance."""
        held = self.__dict__.setdefault("_may_be_blind", {})
        if eps_abs not in held:             # tiny_rows at x = 0 (reach = nu), as one test
            held[eps_abs] = bool(self.span_rows.size) or bool(
                (self.live & (self.nu < eps_abs) & (self.bound < eps_abs)).any())
        return held[eps_abs]

    def blind_rows(self, x: np.ndarray, eps_abs: float) -> np.ndarray:
        """The span rows and the tiny rows at ``x``, in order."""
        return np.union1d(self.span_rows, self.tiny_rows(x, eps_abs))

    def row_test(self, Ax: np.ndarray, z: np.ndarray, eps_abs: float, eps_rel: float) -> bool:
        """(R1'): OSQP's primal test with every constrained row divided by its inf-norm (user's Ax and z)."""
        live, nu = self.live, self.nu[self.live]
        r = np.abs(Ax[live] - z[live]) / nu
        scale = np.maximum(np.abs(Ax[live]), np.abs(z[live])) / nu
        return float(r.max(initial=0.0)) <= eps_abs + eps_rel * float(scale.max(initial=0.0))

    def certifies(self, kind: str, c: np.ndarray) -> bool:
        """True when ``c`` (a confirmed LP certificate, "primal" or "dual") holds entry by entry against the sizes
        it sums, to CERTIFICATE_TOL: each (A'y)_j against (|A'| |y|)_j, S(y) against its terms; each (P d)_j,
        (A d)_i and q'd likewise.  The LPs hold their equations to an absolute tolerance, which a row or column
        scaled by 1e-12 meets with a vector that certifies nothing (issue #46 item 3)."""
        qp, tol = self.qp, CERTIFICATE_TOL
        c = np.asarray(c, dtype=float)
        c = c / max(float(np.max(np.abs(c), initial=0.0)), 1e-300)
        absc = np.abs(c)
        if kind == "primal":
            if np.any((c > 0) & np.isinf(qp.u)) or np.any((c < 0) & np.isinf(qp.l)):
                return False
            terms = np.where(c > 0, qp.u, 0.0) * np.maximum(c, 0.0) + np.where(c < 0, qp.l, 0.0) * np.minimum(c, 0.0)
            return bool(terms.sum() < -tol * np.abs(terms).sum()
                        and np.all(np.abs(qp.At @ c) <= tol * (abs(qp.At) @ absc)))
        Ad, size = qp.A @ c, abs(qp.A) @ absc
        cone = np.all((Ad <= tol * size) | np.isinf(qp.u)) and np.all((Ad >= -tol * size) | np.isinf(qp.l))
        return bool(cone and qp.q @ c < -tol * (np.abs(qp.q) @ absc)
                    and np.all(np.abs(qp.P @ c) <= tol * (abs(qp.P) @ absc)))

    def warnings(self, x: np.ndarray, eps_abs: float, eps_rel: float, row_test: bool | None) -> list[str]:
        """The sentences for ``QPResult.warnings`` at the answer x: which rows and columns, and why."""
        if not (self.void_rows.size or self.span_columns.size or self.may_be_blind(eps_abs)):
            return []           # no span rows, and no row tiny at x = 0, so none tiny at x: nothing to say
        out = []
        nu, top = self.nu, self.nu[self.live].max(initial=0.0)
        held = {None: "", True: "; the run also met the row-normalised test (R1')",
                False: "; the row-normalised test (R1') did not hold, so the run is not reported solved"}[row_test]
        if self.span_rows.size:
            r = self.span_rows
            out.append(f"rows {_indices(r)} have inf-norms {nu[r].min():.2g} to {nu[r].max():.2g}, below "
                       f"1e-10 x the largest row's {top:.2g}: the relative tolerance eps_rel = {eps_rel:g} "
                       f"cannot see their residuals{held}")
        tiny = np.setdiff1d(self.tiny_rows(x, eps_abs), self.span_rows)
        if tiny.size:
            xn = max(1.0, float(np.max(np.abs(x), initial=0.0)))
            out.append(f"rows {_indices(tiny)} have inf-norms {nu[tiny].min():.2g} to {nu[tiny].max():.2g} and "
                       f"bounds below eps_abs = {eps_abs:g}: at max(1, ||x||_inf) = {xn:.3g} the absolute "
                       f"tolerance exceeds every number they hold, so OSQP's primal test cannot fail on them"
                       f"{held}")
        if self.void_rows.size:
            v = self.void_rows
            gap = np.maximum(self.qp.l[v], -self.qp.u[v])
            out.append(f"rows {_indices(v)} have no entries and bounds that exclude 0 (by {gap.min():.2g} to "
                       f"{gap.max():.2g}): no x meets them, so the QP is infeasible, by less than the tolerance "
                       f"if the run ended solved (then reported converged_inaccurate)")
        if self.span_columns.size:
            c, k = self.span_columns, self.kappa
            out.append(f"columns {_indices(c)} of (P; A) have inf-norms {k[c].min():.2g} to {k[c].max():.2g}, "
                       f"below 1e-10 x the largest column's {k.max():.2g}: the dual test cannot see their "
                       f"residuals, so a solved run is reported converged_inaccurate; rescale these variables")
        return out


class QPTermination(StoppingRule):
    """OSQP 1.x's ``check_termination``: residuals (R1), (R2), the duality gap (R3) and infeasibility (I1), (I2).

    Fires when, in the user's problem (unscaled),

        primal <= eps_abs + eps_rel primal_scale,  dual <= eps_abs + eps_rel dual_scale
        and (if ``gap``) abs(gap) <= eps_abs + eps_rel gap_scale                              -> "solved"

    or else, when the primal test failed and dy = y^{k+1} - y^k is a certificate
    (I1) -> "primal_infeasible", or the dual test failed and dx is one (I2) ->
    "dual_infeasible" (``infeasibility=False`` skips both).  After it fired,
    ``outcome`` is one of those three, ``certificate`` the normalised dy or dx
    (None when solved), ``last`` the residuals of the last check and
    ``passed`` which of the primal, dual and gap tests held there.

    When the QP has rows the test cannot see (``ScaleCheck``: span or
    tiny rows), "solved" also needs the row-normalised test (R1'), and
    ``row_test`` keeps its verdict (None when not asked); a confirmed
    certificate is declared only if ``ScaleCheck.certifies`` holds.

    ``tolerance`` is None: the test is itself a KKT test in the user's
    problem, so :func:`admmkit.solve`'s second check (``converged_inaccurate``)
    is not asked for; an infeasibility stop would fail it by nature.
    """

    tolerance = None

    def __init__(self, qp: QP, eps_abs: float = 1e-3, eps_rel: float = 1e-3, *, gap: bool = True,
                 infeasibility: bool = True, eps_prim_inf: float = 1e-4, eps_dual_inf: float = 1e-4):
        self.qp = qp
        for name, v in (("eps_abs", eps_abs), ("eps_rel", eps_rel)):
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if eps_abs == 0 and eps_rel == 0:
            raise ValueError("eps_abs and eps_rel cannot both be 0 (the test could never pass)")
        for name, v in (("eps_prim_inf", eps_prim_inf), ("eps_dual_inf", eps_dual_inf)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        self.eps_abs, self.eps_rel = float(eps_abs), float(eps_rel)
        self.gap, self.infeasibility = bool(gap), bool(infeasibility)
        self.eps_prim_inf, self.eps_dual_inf = float(eps_prim_inf), float(eps_dual_inf)
        tests = "primal+dual+gap" if self.gap else "primal+dual"
        self.name = f"osqp_{tests}(eps_abs={self.eps_abs:g}, eps_rel={self.eps_rel:g})"
        self.scale = ScaleCheck(qp)
        self.names = {SOLVED: self.name, PRIMAL_INFEASIBLE: f"primal_infeasible(eps={self.eps_prim_inf:g})",
                      DUAL_INFEASIBLE: f"dual_infeasible(eps={self.eps_dual_inf:g})"}
        self.reset()

    def _rows_seen(self, rec: IterationRecord) -> bool:
        """True unless the QP has rows OSQP's primal test cannot see (``ScaleCheck``) at this iterate and the
        row-normalised test (R1') fails there; ``row_test`` keeps the verdict (None: no such rows)."""
        qp, scale = self.qp, self.scale
        if not scale.may_be_blind(self.eps_abs):           # no x makes a row blind: nothing to compute
            self.row_test = None
            return True
        x, Axb = qp.relaxed_x(rec.x), rec.Ax
        xu = qp.scaling.unscale_x(x) if qp.scaled else x
        if not scale.blind_rows(xu, self.eps_abs).size:
            self.row_test = None
            return True
        Axb = Axb if x is rec.x and qp.xstep != "kkt" else qp.As @ x
        Ax, z = (Axb / qp.scaling.E, rec.z / qp.scaling.E) if qp.scaled else (Axb, rec.z)
        self.row_test = scale.row_test(Ax, z, self.eps_abs, self.eps_rel)
        return self.row_test

    def kernel_test(self, qp: QP) -> tuple | None:
        """This test's numbers for the segment that makes it in its kernel
        (:func:`admmkit.problems.qp.segment_checks.go_on`): (eps_abs, eps_rel, gap, infeasibility, eps_prim_inf,
        eps_dual_inf, gate, polish_from), gate 0 (no polishing); None for a subclass (it may test more) or a
        test of another QP."""
        if type(self) is not QPTermination or self.qp is not qp:
            return None
        return (self.eps_abs, self.eps_rel, self.gap, self.infeasibility, self.eps_prim_inf, self.eps_dual_inf,
                0.0, 0)

    def reset(self) -> None:
        """Forget the last check (a rule object can serve several runs)."""
        self.row_test: bool | None = None
        self.outcome: str | None = None
        self.certificate: np.ndarray | None = None
        self.last: dict | None = None
        self.passed: dict | None = None

    def fired(self, rec: IterationRecord) -> str | None:
        """The name of the test that fired at this record (see the class docstring), or None; an infeasibility test
        returns a :class:`admmkit.Stop` with status ``primal_infeasible`` / ``dual_infeasible`` and the certificate,
        so that :func:`admmkit.solve` itself ends the run with that status."""
        qp = self.qp
        res = _iterate(qp, rec)
        self.last = res
        primal = qp.m == 0 or res["primal"] <= self.eps_abs + self.eps_rel * res["primal_scale"]
        dual = res["dual"] <= self.eps_abs + self.eps_rel * res["dual_scale"]
        gap = not self.gap or abs(res["gap"]) <= self.eps_abs + self.eps_rel * res["gap_scale"]
        self.passed = {"primal": primal, "dual": dual, "gap": gap}
        if primal and dual and gap and not self._rows_seen(rec):
            self.passed["row_normalised"] = False
            return None                 # OSQP's test held only because it cannot see some rows: go on
        if primal and dual and gap:
            self.outcome, self.certificate = SOLVED, None
            return self.names[SOLVED]
        if not self.infeasibility or (primal and dual):
            return None
        dx, dy = iterate_deltas(qp, rec)
        # a candidate (I1)/(I2) is declared only once the exact LP (C1)/(C2) confirms it, with the LP's certificate
        cert = None if primal else primal_certificate(qp, dy, self.eps_prim_inf)
        if cert is not None and (cert := confirmed_certificate(qp, "primal")) is not None \
                and self.scale.certifies("primal", cert):
            self.outcome, self.certificate = PRIMAL_INFEASIBLE, cert
            return Stop(self.names[PRIMAL_INFEASIBLE], Status.PRIMAL_INFEASIBLE, cert)
        cert = None if (dual or dx is None) else dual_certificate(qp, dx, self.eps_dual_inf)
        if cert is not None and (cert := confirmed_certificate(qp, "dual")) is not None \
                and self.scale.certifies("dual", cert):
            self.outcome, self.certificate = DUAL_INFEASIBLE, cert
            return Stop(self.names[DUAL_INFEASIBLE], Status.DUAL_INFEASIBLE, cert)
        return None
