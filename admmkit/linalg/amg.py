"""Smoothed-aggregation AMG as a preconditioner for the x-step matrices K + rho D (pyamg).

Used by :class:`admmkit.blocks.iterative.IterativeXSolver`; generic: the plug-in gives
the near-null space and, for a vector problem, the dofs of each node.
"""
from __future__ import annotations

import math
import time
from contextlib import contextmanager

import numpy as np
import scipy.sparse as sp

from ..kernels import hand_written


@contextmanager
def _seeded(seed: int = 0):
    """numpy's global random state seeded for the block and restored after it.

    pyamg starts its spectral-radius estimates (Jacobi smoothing of the
    prolongator, the smoothers' weights) from ``np.random.rand``: seeding it
    here makes every AMG set-up, and so every run of an iterative x-step,
    bitwise repeatable, without touching the caller's random stream.
    """
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)


# ---------------------------------------------------------------- node blocks of the AMG
def node_blocks(node: np.ndarray, component: np.ndarray, d: int) -> np.ndarray | None:
    """(n_nodes, d) dof indices grouped by node, or None if some node misses a component.

    With blocks, the AMG works on the node graph (BSR matrices with d x d
    blocks), which is how smoothed aggregation is meant to treat a vector
    problem; without them it works dof by dof.
    """
    node, component = np.asarray(node), np.asarray(component)
    order = np.lexsort((component, node))
    n_nodes = np.count_nonzero(np.bincount(node)) if node.size and node.min() >= 0 else np.unique(node).size
    if n_nodes * d != node.size:
        return None
    blocks = order.reshape(n_nodes, d)
    if not (np.all(component[blocks] == np.arange(d)) and np.all(node[blocks] == node[blocks[:, :1]])):
        return None
    return blocks


# ---------------------------------------------------------------- the AMG preconditioner
class AMGPreconditioner:
    """One V-cycle of a pyamg smoothed-aggregation hierarchy for an SPD matrix.

    With ``blocksize`` d > 1 the hierarchy is built from the BSR form of A (d x d
    node blocks: aggregation on the node graph), then every level is stored in
    CSR and smoothed by pointwise Gauss-Seidel: one forward sweep before and one
    backward sweep after the coarse-grid correction, so the V-cycle is a
    symmetric positive definite operator (needed by CG) at half the cost of
    pyamg's default symmetric sweeps.  pyamg's block Gauss-Seidel on BSR took
    2-3 times as long per V-cycle for the same CG iterations (Example 1,
    4.1e5 unknowns: 310-340 ms against 100-155 ms, 23 iterations each).  The
    finest level of a 3-D vector problem is the exception: it is smoothed by block
    Gauss-Seidel in compiled kernels (``cycle_smoother`` below).  The coarsest
    level is solved by sparse LU.

    Options for speed (the defaults keep pyamg's set-up): ``spectral_steps``
    (:func:`short_spectral_radius`) and ``cycle_values="float32"`` (the V-cycle
    on single-precision values, :class:`admmkit.linalg.vcycle.VCycle`);
    ``cycle_blocks3d=False`` runs the levels of a 3-D vector problem (3 x 3 node
    blocks, six near-null vectors) in CSR instead of :mod:`admmkit.linalg.vcycle_blocks3d`'s blocks;
    ``cycle_smoother`` picks the smoother of such a problem's finest level: block Gauss-Seidel, each node's
    3 x 3 block solved exactly (``"block_gauss_seidel"``, the default, :mod:`admmkit.linalg.vcycle_blockgs3d`:
    9 % fewer CG iterations at the same V-cycle cost, docs/scale.md), pointwise Gauss-Seidel
    (``"gauss_seidel"``, the sweeps of every other level) or damped block Jacobi (``"block_jacobi"``,
    :mod:`admmkit.linalg.vcycle_jacobi3d`).  Other problems (2-D, scalar) and pyamg's own cycle
    (:func:`admmkit.kernels.library_kernels`) keep pointwise Gauss-Seidel whatever it says.
    ``finest3d``: for such a problem with ``spectral_steps`` set, the finest level's set-up in compiled
    loops (:mod:`admmkit.linalg.amg_finest3d`, pyamg's arrays bit for bit, the levels below pyamg's);
    False, or under :func:`admmkit.kernels.library_kernels`, pyamg's set-up of every level.
    """

    SMOOTHERS = (("gauss_seidel", {"sweep": "forward"}), ("gauss_seidel", {"sweep": "backward"}))
    #: sparse LU on the coarsest level: pyamg's default, a dense pseudo-inverse (SVD), took
    #: 0.1 s for 500 x 500 on one thread and 0.6-2.3 s on two threads of this loaded machine
    COARSE = "splu"
    #: no relaxation of the near-null space before fitting the prolongators: the rigid body modes are
    #: exact null vectors of K already.  pyamg's default (4 block Gauss-Seidel sweeps) took 40 % of the
    #: setup (Example 1, 4.1e5 unknowns: 2.9-3.3 s against 1.7-1.8 s) for the same 23 CG iterations
    IMPROVE = None

    def __init__(self, A: sp.spmatrix, near_null: np.ndarray | None, *, blocksize: int = 1, max_coarse: int = 500,
                 D: sp.spmatrix | None = None, rho: float | None = None, spectral_steps: int | None = None,
                 cycle_values: str = "float64", cycle_blocks3d: bool = True,
                 cycle_smoother: str = "block_gauss_seidel", finest3d: bool = True):
        if cycle_smoother not in ("gauss_seidel", "block_gauss_seidel", "block_jacobi"):  # vcycle.SMOOTHERS
            raise ValueError(f"cycle_smoother must be gauss_seidel, block_gauss_seidel or block_jacobi, got "
                             f"{cycle_smoother!r}")
        import pyamg
        from pyamg.relaxation.smoothing import change_smoothers
        start = time.perf_counter()
        A = sp.csr_matrix(A)
        options = dict(symmetry="symmetric", max_coarse=max_coarse, presmoother=self.SMOOTHERS[0],
                       postsmoother=self.SMOOTHERS[1], keep=False, coarse_solver=self.COARSE,
                       improve_candidates=self.IMPROVE)
        with _seeded(), short_spectral_radius(spectral_steps):
            self.ml = None
            if finest3d and blocksize == 3 and spectral_steps is not None and near_null is not None and hand_written():
                self.ml = _compiled_finest(A, near_null, options)
            if self.ml is None:
                An = A.tobsr(blocksize=(blocksize, blocksize)) if blocksize > 1 else A
                self.ml = pyamg.smoothed_aggregation_solver(An, B=near_null, **options)
            if blocksize > 1:         # the finest level is A itself, not a CSR copy of its BSR form
                for level, M in zip(self.ml.levels, [A] + [level.A for level in self.ml.levels[1:]]):
                    level.A = _symmetric_csr(M)
                change_smoothers(self.ml, self.SMOOTHERS[0], self.SMOOTHERS[1])
        # A = K + rho D gives A_l = K_l + rho D_l on every level with D_l = R D_{l-1} P: keep the coarse
        # D_l on the coarse patterns, so that a Galerkin refresh for another rho is one axpy per level
        self._rho, self._pencils = rho, None
        self._D, self._fine_entries = (sp.csr_matrix(D) if D is not None else None), None
        if D is not None and rho is not None:
            pencils, Dl = [], sp.csr_matrix(D)
            for fine, coarse in zip(self.ml.levels[:-1], self.ml.levels[1:]):
                Dl = galerkin_on_support(Dl, fine.P)       # R D_l P with R = P' (the hierarchy is symmetric)
                pencils.append(PencilMatrix(coarse.A, Dl))
                # the same values on the pencil's pattern, which every refresh keeps (the V-cycle then reuses
                # what it found on it), in an array of the level's own: the first change of rho then rewrites
                # D_l's entries in place too, where a level holding its pencil's K forced a full refresh
                # (the cycle's blocks laid out again: 2 s at 1e6 unknowns in 3D)
                coarse.A = _symmetric_csr(_own_values(pencils[-1].K_matrix()))
            self._pencils = pencils
        self._cycle = None        # the compiled V-cycle (admmkit.linalg.vcycle), built at the first application
        self.cycle_values = np.dtype(cycle_values)
        self.cycle_blocks3d = bool(cycle_blocks3d)
        self.cycle_smoother = cycle_smoother
        self.setup_time = time.perf_counter() - start
        self.refresh_time = math.nan

    @property
    def levels(self) -> int:
        """Number of levels of the hierarchy."""
        return len(self.ml.levels)

    def operator_complexity(self) -> float:
        """Sum of the nonzeros of all levels over those of the finest."""
        return float(self.ml.operator_complexity())

    def refresh(self, A: sp.spmatrix, rho: float | None = None) -> None:
        """Galerkin refresh: keep the prolongators, make every level R A P for the new A and the smoothers.

        With the D and rho of the construction and the new ``rho``, the coarse
        operators are updated as A_l + (rho - rho_0) D_l (exact, one axpy per
        level); otherwise R A P is recomputed level by level.
        """
        from pyamg.multilevel import coarse_grid_solver
        from pyamg.relaxation.smoothing import change_smoothers
        start = time.perf_counter()
        if self._refresh_in_place(A, rho):
            self.refresh_time = time.perf_counter() - start
            return
        levels = self.ml.levels
        levels[0].A = _symmetric_csr(A)
        if self._pencils is not None and rho is not None:
            for coarse, pencil in zip(levels[1:], self._pencils):
                coarse.A = _symmetric_csr(pencil.at(rho - self._rho))
        else:
            for fine, coarse in zip(levels[:-1], levels[1:]):
                coarse.A = _symmetric_csr(fine.R @ fine.A @ fine.P)
        with _seeded():
            change_smoothers(self.ml, self.SMOOTHERS[0], self.SMOOTHERS[1])
        self.ml.coarse_solver = coarse_grid_solver(self.COARSE)  # its cached factors belonged to the old A
        if self._cycle is not None:
            self._cycle = self._cycle.refreshed(self.ml)
        self.refresh_time = time.perf_counter() - start

    def _refresh_in_place(self, A: sp.spmatrix, rho: float | None) -> bool:
        """The Galerkin refresh for a new rho where only D's entries change, made in place; False (nothing
        done) where it does not apply.

        It applies with the compiled cycle, after a first refresh, when A is the finest level's matrix updated
        in place at D's entries (:meth:`PencilMatrix.update`) and D is sparse on every coarse pattern.  Then
        every level changes only where D_l is stored: those values are rewritten as A_l + (rho - rho_0) D_l
        (the axpy of :meth:`refresh`, the same values), in the cycle's storage too, with their rows' 1 / a_ii,
        and the coarsest LU is made again.  The full refresh copied every level's values and laid the cycle's
        blocks out anew: 0.6 s a change of rho at 1e6 unknowns (the 3D block), with the copies of A and
        of CG's product made before it.
        """
        from pyamg.multilevel import coarse_grid_solver
        levels = self.ml.levels
        if not (hand_written() and self._cycle is not None and self._pencils is not None and rho is not None
                and len(levels) > 1 and sp.issparse(A) and A.format == "csr" and _same_values(A, levels[0].A)):
            return False
        entries = [pencil.changed_entries() for pencil in self._pencils]
        if any(e is None for e in entries) or any(np.may_share_memory(level.A.data, pencil.K_data)
                                                   for level, pencil in zip(levels[1:], self._pencils)):
            return False              # D dense on a level, or a level still holds its pencil's K: refresh anew
        if self._fine_entries is None:
            self._fine_entries = entry_positions(levels[0].A, self._D)
            if self._fine_entries is None:
                return False
        self._cycle.update_entries(0, levels[0].A, self._fine_entries)
        for lvl, (pencil, changed) in enumerate(zip(self._pencils, entries), 1):
            pencil.update(levels[lvl].A, rho - self._rho)
            if lvl < len(levels) - 1:
                self._cycle.update_entries(lvl, levels[lvl].A, changed)
        self.ml.coarse_solver = coarse_grid_solver(self.COARSE)  # its cached factors belonged to the old A
        self._cycle.coarse_solver = self.ml.coarse_solver
        return True

    #: ``self(r, out=z)`` writes the cycle into z (what :func:`admmkit.linalg.cg.pcg` asks for)
    writes_into = True

    def __call__(self, r: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """z = V-cycle(r), starting from zero (no residual norms, unlike ml.solve); into ``out`` if given.

        With numba, :class:`admmkit.linalg.vcycle.VCycle` (the same values, its products row-parallel);
        without, or under :func:`admmkit.kernels.library_kernels`, pyamg's own cycle.
        """
        if hand_written():
            if self._cycle is None:
                from .vcycle import VCycle
                self._cycle = VCycle(self.ml, values=self.cycle_values, blocks3d=self.cycle_blocks3d,
                                     smoother=self.cycle_smoother)
            return self._cycle(r, out=out)
        if len(self.ml.levels) == 1:
            z = self.ml.coarse_solver(self.ml.levels[0].A, r)
        else:
            z = np.zeros_like(r)
            self.ml._MultilevelSolver__solve(0, z, r, "V")  # pyamg's cycle, without ml.solve's two residual norms
        if out is None:
            return z
        out[...] = z
        return out


def _compiled_finest(A: sp.csr_matrix, near_null: np.ndarray, options: dict):
    """pyamg's hierarchy of A with the finest level made by :func:`admmkit.linalg.amg_finest3d.finest_level` and
    the levels below by pyamg from its Galerkin product; None where that does not apply."""
    import pyamg
    from pyamg.aggregation import smooth
    from pyamg.multilevel import MultilevelSolver
    from pyamg.relaxation.smoothing import change_smoothers
    from .amg_finest3d import finest_level
    made = finest_level(A, near_null, smooth.approximate_spectral_radius, options["max_coarse"])
    if made is None:
        return None
    level, A1, B1 = made
    below = pyamg.smoothed_aggregation_solver(A1, B=B1, max_levels=MAX_LEVELS - 1, **options)
    ml = MultilevelSolver([level] + below.levels, coarse_solver=options["coarse_solver"])
    change_smoothers(ml, options["presmoother"], options["postsmoother"])
    return ml


#: pyamg's default number of levels at most
MAX_LEVELS = 10


@contextmanager
def short_spectral_radius(steps: int | None):
    """pyamg's prolongation smoothing estimates rho(D^-1 A) with ``steps`` Arnoldi steps and no restart.

    pyamg's default (15 steps, up to 5 restarts: two passes here) took 3.2 s of a 5.3 s set-up
    at 1e6 unknowns (Example 1); 10 steps gave rho 1.2 % lower on the finest level (3.067 against
    3.105) and 82 CG iterations instead of 83 in the whole SADMM run, with a 2.8 s set-up.  The
    steps run in :func:`admmkit.linalg.arnoldi.arnoldi_spectral_radius` (pyamg's values, fewer temporaries).
    ``None`` keeps pyamg's default.  Scoped: pyamg's module attribute is restored on exit.
    """
    if steps is None:
        yield
        return
    import functools
    from pyamg.aggregation import smooth
    from .arnoldi import arnoldi_spectral_radius
    original = smooth.approximate_spectral_radius
    smooth.approximate_spectral_radius = functools.partial(arnoldi_spectral_radius, steps=int(steps))
    try:
        yield
    finally:
        smooth.approximate_spectral_radius = original


def entry_positions(pattern: sp.csr_matrix, M: sp.csr_matrix) -> np.ndarray | None:
    """Where M's stored entries sit in the values of the sorted CSR ``pattern``, or None if one lies outside it.

    Reads only the pattern rows M touches (D couples the few contact dofs: at 1e6 unknowns this
    replaced keys for all 14e6 entries of K, twice, about 0.4 s).
    """
    if M.nnz == 0:
        return np.empty(0, dtype=np.int64)
    rows = np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))
    touched = np.unique(rows)
    starts, lengths = pattern.indptr[touched], np.diff(pattern.indptr)[touched]
    at = np.repeat(starts - np.concatenate(([0], np.cumsum(lengths)[:-1])), lengths) + np.arange(lengths.sum())
    width = pattern.shape[1] + 1
    keys_union = np.repeat(touched, lengths).astype(np.int64) * width + pattern.indices[at]
    keys = rows.astype(np.int64) * width + M.indices
    pos = np.minimum(np.searchsorted(keys_union, keys), keys_union.size - 1)
    if keys_union.size == 0 or not np.array_equal(keys_union[pos], keys):
        return None
    return at[pos]


def _same_values(A, B) -> bool:
    """A and B hold their values in the same memory (scipy's constructors make views of the arrays they
    are given, not the arrays themselves)."""
    return A.data.shape == B.data.shape and np.may_share_memory(A.data, B.data)


def galerkin_on_support(D: sp.spmatrix, P) -> sp.csr_matrix:
    """P' D P from the rows of P (CSR, or BSR: whole block rows) that D's nonzero rows touch.

    The sums are scipy's ``P.T @ D @ P`` term by term in the same order (a row of P that meets no nonzero
    row of D adds nothing there), so the values are the same bit for bit; but P' is not transposed and
    converted whole.  For contact, D lives on the contact dofs: at h = 1/32 in 3D (3.1e5 unknowns) the
    finest level's product took 0.018 s against 0.17 s.
    """
    D = sp.csr_matrix(D)
    rows = np.flatnonzero(np.diff(D.indptr))
    size = P.blocksize[0] if P.format == "bsr" else 1
    blocks = np.unique(rows // size)
    if P.format == "bsr":
        starts, counts = P.indptr[blocks], P.indptr[blocks + 1] - P.indptr[blocks]
        indptr = np.concatenate(([0], np.cumsum(counts)))
        take = np.repeat(starts - indptr[:-1], counts) + np.arange(indptr[-1])
        rows_of_P = sp.bsr_matrix((P.data[take], P.indices[take], indptr), shape=(blocks.size * size, P.shape[1]),
                                  blocksize=P.blocksize)
    else:
        rows_of_P = sp.csr_matrix(P)[blocks]
    dofs = (blocks[:, None] * size + np.arange(size)).ravel()
    return sp.csr_matrix(rows_of_P.T @ D[dofs][:, dofs] @ rows_of_P)


def _own_values(M: sp.csr_matrix) -> sp.csr_matrix:
    """M's matrix with a copy of its values on the same pattern (the index arrays shared, kept sorted)."""
    copy = sp.csr_matrix((M.data.copy(), M.indices, M.indptr), shape=M.shape)
    copy.has_sorted_indices = M.has_sorted_indices
    return copy


def _symmetric_csr(A) -> sp.csr_matrix:
    """A as CSR, flagged symmetric for pyamg."""
    A = sp.csr_matrix(A)
    A.symmetry = "symmetric"
    return A


# ---------------------------------------------------------------- K + rho D on one pattern
class PencilMatrix:
    """K + rho D for any rho without sparse additions: both on the union of their patterns.

    The union pattern is stored once in CSR (blocksize 1) or BSR (d x d blocks,
    what the smoothed aggregation of a vector problem wants); ``at(rho)``
    returns the matrix with data K_data + rho D_data, one axpy of the values.
    """

    def __init__(self, K: sp.csr_matrix, D: sp.csr_matrix, blocksize: int = 1, copy: bool = True):
        self.shape = K.shape
        self.blocksize = blocksize
        if blocksize == 1:     # fast path: D's entries all inside K's pattern (the usual case: D couples
            K = sp.csr_matrix(K, copy=copy)   # dofs of one contact node or edge, which K couples too)
            K.sum_duplicates()
            K.sort_indices()
            self.pattern = K
            D = sp.csr_matrix(D)
            D.sum_duplicates()
            positions = self._positions(D)
            if positions is not None:
                self.K_data = K.data          # the pattern's own values: K (never written)
                self.D_data = np.zeros(K.data.shape, dtype=K.data.dtype)  # calloc: pages D never touches
                # stay unwritten (zeros_like wrote all 360 MB at 1e6 unknowns in 3D, 0.34 s at 3e5)
                self.D_data[positions] = D.data
                self._D_entries = np.sort(positions[D.data != 0])   # where D_data is nonzero, from D's own entries
                return
        ones = lambda M: sp.csr_matrix((np.ones_like(M.data), M.indices, M.indptr), shape=M.shape)  # noqa: E731
        pattern = (ones(K) + ones(D)).tocsr()     # positive values: no entry of the union cancels
        if blocksize > 1:
            pattern = pattern.tobsr(blocksize=(blocksize, blocksize))
        pattern.sort_indices()
        self.pattern = pattern
        self.K_data = self._aligned(K)
        self.D_data = self._aligned(D)

    def K_matrix(self):
        """K on the pattern (the pattern itself on the fast path: no copy)."""
        if self.pattern.data is self.K_data:
            return self.pattern
        return self.at(0.0)

    def _positions(self, M: sp.csr_matrix) -> np.ndarray | None:
        """Where M's stored entries sit in the (CSR) pattern's values, or None if one lies outside it."""
        return entry_positions(self.pattern, M)

    def _keys(self, M) -> np.ndarray:
        rows = np.repeat(np.arange(M.indptr.size - 1), np.diff(M.indptr))
        return rows.astype(np.int64) * (self.shape_blocks + 1) + M.indices

    @property
    def shape_blocks(self) -> int:
        """Number of block columns."""
        return self.pattern.shape[1] // self.blocksize

    def _aligned(self, M: sp.csr_matrix) -> np.ndarray:
        """M's values placed on the union pattern (zeros elsewhere)."""
        bs = self.blocksize
        M = M.tobsr(blocksize=(bs, bs)) if bs > 1 else sp.csr_matrix(M)
        M.sort_indices()
        M.sum_duplicates()
        keys_union, keys = self._keys(self.pattern), self._keys(M)
        pos = np.searchsorted(keys_union, keys)
        if keys.size and not np.array_equal(keys_union[np.minimum(pos, keys_union.size - 1)], keys):
            raise AssertionError("pattern of a term is not inside the union pattern")  # by construction
        data = np.zeros_like(self.pattern.data)
        data[pos] = M.data
        return data

    def changed_entries(self) -> np.ndarray | None:
        """The positions in the pattern's values (CSR) where D is nonzero, the only ones a change of rho
        changes; None for a BSR pattern."""
        if getattr(self, "_D_entries", None) is None:
            self._D_entries = np.flatnonzero(self.D_data) if self.D_data.ndim == 1 else np.empty(0, dtype=int)
        return self._D_entries if self.D_data.ndim == 1 else None

    def update(self, A, rho: float):
        """A matrix ``at`` returned, made K + rho D for this rho in place: only D's entries are rewritten,
        as K + rho D (the values of ``at(rho)`` bit for bit, without a copy of K's values).  Returns A."""
        entries = self.changed_entries()
        if entries is None:
            np.add(self.K_data, rho * self.D_data, out=A.data)
        else:
            A.data[entries] = self.K_data[entries] + rho * self.D_data[entries]
        return A

    def at(self, rho: float):
        """The sparse matrix K + rho D (CSR or BSR); where D is sparse in the pattern (contact: 4e3 of 14e6
        entries), K's values are copied and only D's entries updated (the same values, a third of the work)."""
        if getattr(self, "_D_entries", None) is None:
            self._D_entries = np.flatnonzero(self.D_data) if self.D_data.ndim == 1 else np.empty(0, dtype=int)
        if 0 < self._D_entries.size < self.D_data.size // 8:
            data = self.K_data.copy()
            data[self._D_entries] += rho * self.D_data[self._D_entries]
        else:
            data = self.K_data + rho * self.D_data
        if self.blocksize > 1:
            return sp.bsr_matrix((data, self.pattern.indices, self.pattern.indptr), shape=self.shape)
        A = sp.csr_matrix((data, self.pattern.indices, self.pattern.indptr), shape=self.shape)
        A.has_sorted_indices = True          # the pattern's rows are sorted (__init__): no scan of its indices
        return A
