"""Acceleration of the ADMM fixed-point iteration: safeguarded Anderson and restarted fast ADMM.

One ADMM iteration at a fixed rho is a map T of the *state* it starts from,

    s = (u, lam),   u = z^k (order "xz": the x-step reads z and lam)
                    u = A x^k (order "zx": the z-step reads A x and lam),

and a solution is a fixed point s = T(s).  An accelerator sees, after each
iteration, the state s_k it started from and its image f_k = T(s_k), and
proposes the state s_{k+1} the next iteration starts from (plain ADMM:
s_{k+1} = f_k).  Residuals and distances are measured in the norm::

    ||(u, lam)||_W^2 = rho ||u||_M^2 + ||lam||_M^2 / rho,               (A1)

in which T is firmly nonexpansive for convex problems (the Douglas-Rachford
form of ADMM; M is the problem's inner product).  The fixed-point residual is
g_k = f_k - s_k.

* :class:`Anderson`: type-II Anderson acceleration with memory m (Walker &
  Ni 2011; Zhang, O'Donoghue & Boyd 2020, as in SCS 3)::

      gamma   = argmin_gamma ||g_k - dG gamma||_W                       (A2)
      s_{k+1} = f_k - dF gamma                                          (A3)

  with dG, dF the last m differences of g and f.  Interval (SCS >= 3.2's
  ``acceleration_interval``, k): the step (A2)-(A3) follows every k-th
  iteration only, on that iteration's pair (s_k, f_k), so the differences
  are between pairs k iterations apart and the other iterations are plain
  (s_{k+1} = f_k): a step costs 1/k of it per iteration.  Safeguard (SCS 3): when
  the residual at an extrapolated state exceeds ``safeguard`` times the
  residual before it, the extrapolation is rejected, the memory cleared and
  the run goes on from the plain image f of the state before it.  Rejections
  back off: the next b proposals are plain, b doubling with every rejection
  (up to BACKOFF_MAX) and back to 1 after an accepted extrapolation, so that
  where extrapolation keeps failing the run is plain ADMM with rare probes
  (HS268 at 1e-6: 1310 of 1376 extrapolations rejected and the run stalled
  at the cap without it).  For a problem whose inner product is a weighted
  dot product (``problem.inner_weights()``) the steps are one kernel,
  ``admmkit.loop.anderson_kernel``, which a compiled segment calls too.
* :class:`FastADMM`: the restarted fast ADMM of Goldstein, O'Donoghue,
  Setzer & Baraniuk (2014, Algorithm 8): Nesterov momentum on the state::

      c_k = ||g_k||_W^2;  if c_k < eta c_{k-1}:                          (A4)
          a_{k+1} = (1 + sqrt(1 + 4 a_k^2)) / 2
          s_{k+1} = f_k + (a_k - 1) / a_{k+1} (f_k - f_{k-1})           (A5)
      else (restart): a_{k+1} = 1, s_{k+1} = f_{k-1}, c_k = c_{k-1} / eta
          (s_{k+1} = f_k, c_k kept, when s_k was not extrapolated: f_{k-1}
          is then s_k and going back would repeat the iteration).

  Safeguard (A6), in the spirit of Anderson's: a restart that ends a
  momentum phase of fewer than ``patience`` extrapolations fails it, and
  the next b steps are plain, b doubling with every failure (up to
  BACKOFF_MAX) and back to 1 after a phase that lasted; momentum starts
  afresh after them.  Under OSQP's adaptive rho, where momentum rarely
  lasts, the run becomes plain ADMM with rare probes (HS268 and QADLITTL at
  1e-6, which the restarts alone left at the cap of 4000, are solved).
  Global fallback (A7): the ``give_up``-th short failed phase in a row
  (fewer than 4 extrapolations: momentum did not get going; a longer phase
  starts the count again) turns momentum off for good.  The probes are not free under an adaptive rho:
  each failed phase wastes an iteration and moves the iterate the rule
  reads, so rho's path (OSQP's, chosen from the residuals at fixed
  iterations) drifts from plain ADMM's (QBEACONF at 1e-6: 13 failed
  phases, the last four beyond iteration 500, and 4025 iterations against
  plain's 3450; with give_up = 4, 3125).
  For a weighted dot product the steps are one kernel too,
  ``admmkit.loop.fast_kernel``, which a compiled segment calls as it calls
  Anderson's.

A fixed point of T is a fixed point of both accelerated maps (g = 0 gives
gamma = 0 in (A2), and f_k = f_{k-1} = s_k in (A5)).  A change of rho changes
T and the norm (A1): the loop then calls :meth:`Accelerator.reset`, so no
rule has to know about acceleration.  The proposals are deterministic
functions of the iterates.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from . import anderson_kernel, fast_kernel
from ..kernels import compiled_now
from .anderson_kernel import BACKOFF_MAX      # the longest run of plain steps Anderson takes after a rejection

#: Anderson's default interval (iterations per step); docs/qp.md, "Anderson", says how it was chosen
INTERVAL = 10
#: fast ADMM's default patience (extrapolations a momentum phase must last); docs/qp.md, "Restarted fast ADMM
#: safeguarded", says how it was chosen
PATIENCE = 16
#: fast ADMM's default global fallback (short failed phases in a row that end momentum for good); docs/qp.md,
#: "Restarted fast ADMM: the global fallback", says how it was chosen
GIVE_UP = 4

State = tuple  # (u, lam): two arrays of the constraint space


class Accelerator(ABC):
    """Proposes the state of the next ADMM iteration from the last state and its image."""

    #: a short name for results and reports
    name = "accelerator"

    def __init__(self):
        self.stats = {"extrapolated": 0, "rejected": 0, "restarts": 0}

    def reset(self) -> None:
        """Forget the past (at the start of a run and at every change of rho)."""

    def start(self) -> None:
        """Start a run: clear the memory and the counts."""
        self.reset()
        self.stats = {k: 0 for k in self.stats}

    @abstractmethod
    def propose(self, s: State, f: State, rho: float, inner) -> State:
        """s_{k+1} from s_k, f_k = T(s_k) and rho; ``inner(a, b)`` is the problem's M inner product."""

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in vars(self).items() if not k.startswith("_") and k != "stats")
        return f"{type(self).__name__}({params})"


def w_inner(a: State, b: State, rho: float, inner) -> float:
    """<a, b>_W = rho <u_a, u_b>_M + <lam_a, lam_b>_M / rho (A1)."""
    return rho * inner(a[0], b[0]) + inner(a[1], b[1]) / rho


def _diff(a: State, b: State) -> State:
    return a[0] - b[0], a[1] - b[1]


class KernelAccelerator(Accelerator):
    """An accelerator whose steps, for a weighted inner product, are one kernel on arrays (its subclass's
    :meth:`kernel_arrays`), taken alike by the loop and by a compiled segment (bit for bit)."""

    def __init__(self):
        super().__init__()
        self._arrays = self._weights = None       # the kernel's arrays, for a weighted inner product (bind)
        self._length = 0                          # the stacked state's length 2 m

    def kernel_arrays(self, length: int):
        """New arrays of the kernel's state for stacked states of ``length`` entries."""
        raise NotImplementedError

    def bind(self, weights: np.ndarray | None, size: int | None) -> None:
        """Take the steps with the kernel for the inner product (a, b)_M = sum_i ``weights``_i a_i b_i on
        vectors of length ``size`` (the loop's and a segment's steps then agree bit for bit); None: the
        problem's ``inner`` (numpy)."""
        if weights is None:
            self._arrays = self._weights = None
            return
        self._weights = np.ascontiguousarray(weights, dtype=np.float64)
        self._length = 2 * int(size)
        self._arrays = self.kernel_arrays(self._length)

    def start(self) -> None:
        """Start a run: the counts cleared, and the kernel's arrays made anew where it is bound."""
        super().start()
        if self._arrays is not None:
            self._arrays = self.kernel_arrays(self._length)


class Anderson(KernelAccelerator):
    """Safeguarded type-II Anderson acceleration, memory ``m`` (eqs. (A2)-(A3)).

    Parameters
    ----------
    m : int
        Memory, an integer >= 1 (SCS's default is 10).
    interval : int
        Take a step after every ``interval``-th iteration, the others plain
        (SCS's ``acceleration_interval``); an integer >= 1, 1 a step after
        every iteration.  The default, INTERVAL, was chosen by measurement
        (docs/qp.md, "Anderson").
    safeguard : float
        Reject an extrapolated state whose residual exceeds ``safeguard``
        times the residual of the state before it (>= 1; SCS uses 1).
    regularization : float
        Tikhonov term of the least-squares problem (A2), relative to the
        largest diagonal entry of its Gram matrix (>= 0).
    """

    name = "anderson"

    def __init__(self, m: int = 10, safeguard: float = 1.0, regularization: float = 1e-10,
                 interval: int | None = None):
        if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
            raise ValueError(f"Anderson: m (the memory) must be an integer >= 1, got {m!r}")
        interval = INTERVAL if interval is None else interval
        if isinstance(interval, bool) or not isinstance(interval, (int, np.integer)) or interval < 1:
            raise ValueError(f"Anderson: interval (iterations per step) must be an integer >= 1, got {interval!r}")
        if not (isinstance(safeguard, (int, float)) and math.isfinite(safeguard) and safeguard >= 1):
            raise ValueError(f"Anderson: safeguard must be a finite number >= 1, got {safeguard!r}")
        if not (isinstance(regularization, (int, float)) and math.isfinite(regularization) and regularization >= 0):
            raise ValueError(f"Anderson: regularization must be a finite number >= 0, got {regularization!r}")
        super().__init__()
        self.m, self.safeguard, self.regularization = int(m), float(safeguard), float(regularization)
        self.interval = int(interval)
        self._skip, self._backoff = 0, 1
        self.reset()

    def kernel_arrays(self, length: int):
        """``admmkit.loop.anderson_kernel.AndersonArrays`` of this memory and interval."""
        return anderson_kernel.AndersonArrays(self.m, length, self.interval)

    def start(self) -> None:
        """Start a run: clear the memory, the counts and the back-off."""
        super().start()
        self._skip, self._backoff = 0, 1

    def reset(self) -> None:
        """Clear the memory (the differences and the last plain image) and the clock; the back-off stays."""
        self._clock = 0                   # iterations since the last step
        self._f = self._g = None          # f_{k-1}, g_{k-1}
        self._dF, self._dG = [], []        # differences, oldest first
        self._gram = np.zeros((0, 0))     # <dG_i, dG_j>_W
        self._fallback = None             # (f of the state before an extrapolation, its residual norm)
        if getattr(self, "_arrays", None) is not None:
            self._arrays.reset()

    def kernel_state(self):
        """(weights, safeguard, regularization, arrays) for a compiled segment's steps, or None when unbound."""
        if self._arrays is None:
            return None
        return self._weights, self.safeguard, self.regularization, self._arrays

    def sync_stats(self) -> None:
        """The counts from the kernel's arrays (after steps taken there)."""
        if self._arrays is not None:
            self.stats["extrapolated"] = int(self._arrays.ist[anderson_kernel.EXTRAPOLATED])
            self.stats["rejected"] = int(self._arrays.ist[anderson_kernel.REJECTED])

    def propose(self, s: State, f: State, rho: float, inner) -> State:
        """The next state: an Anderson extrapolation, f itself, or the fallback after a rejection."""
        if self._arrays is not None:
            return self._propose_kernel(s, f, rho)
        due = self._clock + 1 >= self.interval
        if not due and self._fallback is None:                # between steps: plain
            self._clock += 1
            return f
        g = _diff(f, s)
        g_norm = math.sqrt(max(w_inner(g, g, rho, inner), 0.0))
        if self._fallback is not None:                        # s was extrapolated: the safeguard looks at it
            plain, before = self._fallback
            self._fallback = None
            if not g_norm <= self.safeguard * before:         # NaN counts as a rejection
                self.stats["rejected"] += 1
                self.reset()
                self._skip, self._backoff = self._backoff, min(2 * self._backoff, BACKOFF_MAX)   # back off
                return plain
            self._backoff = 1
            if not due:                                       # accepted, and no step due: plain
                self._clock += 1
                return f
        self._clock = 0
        if self._f is not None:
            self._push(_diff(f, self._f), _diff(g, self._g), rho, inner)
        self._f, self._g = f, g
        if not self._dG:
            return f
        if self._skip > 0:                                    # backing off after a rejection: a plain step
            self._skip -= 1
            return f
        gamma = self._least_squares(g, rho, inner)                                      # (A2)
        if gamma is None:
            return f
        u = f[0] - sum(c * d[0] for c, d in zip(gamma, self._dF))                        # (A3)
        lam = f[1] - sum(c * d[1] for c, d in zip(gamma, self._dF))
        self._fallback = (f, g_norm)
        self.stats["extrapolated"] += 1
        return u, lam

    def _propose_kernel(self, s: State, f: State, rho: float) -> State:
        """:meth:`propose` by ``admmkit.loop.anderson_kernel.anderson_update`` on the stacked states."""
        out = np.empty_like(f[0]), np.empty_like(f[1])
        anderson_kernel.anderson_update(float(rho), self._weights, self.safeguard, self.regularization, *s, *f, *out,
                        *self._arrays.args())
        self.sync_stats()
        return out

    def _push(self, df: State, dg: State, rho: float, inner) -> None:
        """Append a difference pair and update the Gram matrix (dropping the oldest beyond m)."""
        if len(self._dG) == self.m:
            self._dF.pop(0)
            self._dG.pop(0)
            self._gram = self._gram[1:, 1:]
        row = np.array([w_inner(dg, d, rho, inner) for d in self._dG] + [w_inner(dg, dg, rho, inner)])
        n = row.size
        gram = np.empty((n, n))
        gram[:n - 1, :n - 1] = self._gram
        gram[n - 1, :] = gram[:, n - 1] = row
        self._gram = gram
        self._dF.append(df)
        self._dG.append(dg)

    def _least_squares(self, g: State, rho: float, inner):
        """gamma of (A2) from the normal equations (Tikhonov-regularised); None if they are not finite."""
        rhs = np.array([w_inner(d, g, rho, inner) for d in self._dG])
        gram = self._gram + self.regularization * max(float(np.max(np.diag(self._gram))), 0.0) * np.eye(rhs.size)
        try:
            gamma = np.linalg.lstsq(gram, rhs, rcond=None)[0]
        except np.linalg.LinAlgError:
            return None
        return gamma if np.all(np.isfinite(gamma)) else None


class FastADMM(KernelAccelerator):
    """Safeguarded restarted fast ADMM (Goldstein et al. 2014, Algorithm 8; eqs. (A4)-(A6)).

    Parameters
    ----------
    eta : float
        Restart when the combined residual c_k is not below ``eta`` c_{k-1};
        in (0, 1) (the paper uses 0.999).
    patience : int
        The safeguard (A6): a restart that ends a momentum phase of fewer
        than ``patience`` extrapolations fails it, and the next b steps are
        plain, b doubling with each failure (up to BACKOFF_MAX) and back to 1
        after a phase that lasted.  An integer >= 0; 0 never backs off (the
        restarts alone).  The default, PATIENCE, was chosen by measurement
        (docs/qp.md, "Restarted fast ADMM safeguarded").
    give_up : int
        The global fallback (A7): the ``give_up``-th short failed phase in
        a row (fewer than ``fast_kernel.SHORT`` = 4 extrapolations: momentum
        did not get going; a longer phase starts the count again) turns
        momentum off for good (the run is plain ADMM after it, at plain
        ADMM's cost).  An integer >= 0; 0 never gives up.  The
        default, GIVE_UP, was chosen by measurement (docs/qp.md, "Restarted
        fast ADMM: the global fallback").
    """

    name = "fast"

    def __init__(self, eta: float = 0.999, patience: int | None = None, give_up: int | None = None):
        if isinstance(eta, bool) or not (isinstance(eta, (int, float)) and 0 < eta < 1):
            raise ValueError(f"FastADMM: eta must be a number in (0, 1), got {eta!r}")
        patience = PATIENCE if patience is None else patience
        if isinstance(patience, bool) or not isinstance(patience, (int, np.integer)) or patience < 0:
            raise ValueError(f"FastADMM: patience (extrapolations a momentum phase must last) must be an integer "
                             f">= 0, got {patience!r}")
        give_up = GIVE_UP if give_up is None else give_up
        if isinstance(give_up, bool) or not isinstance(give_up, (int, np.integer)) or give_up < 0:
            raise ValueError(f"FastADMM: give_up (failed momentum phases in a row that end momentum) must be an "
                             f"integer >= 0, got {give_up!r}")
        super().__init__()
        self.eta, self.patience, self.give_up = float(eta), int(patience), int(give_up)
        self._skip, self._backoff, self._streak = 0, 1, 0
        self.reset()

    def kernel_arrays(self, length: int):
        """``admmkit.loop.fast_kernel.FastArrays`` for stacked states of ``length`` entries, this patience and
        give_up."""
        return fast_kernel.FastArrays(length, self.patience, self.give_up)

    def start(self) -> None:
        """Start a run: clear the memory, the counts, the back-off and the failed phases in a row."""
        super().start()
        self._skip, self._backoff, self._streak = 0, 1, 0

    def reset(self) -> None:
        """Restart: no momentum, no previous image (a change of rho); the back-off and the fallback stay."""
        self._a, self._c, self._f = 1.0, math.inf, None
        self._momentum, self._phase = False, 0        # s_k extrapolated; extrapolations since the last restart
        if getattr(self, "_arrays", None) is not None:
            self._arrays.reset()

    def kernel_state(self):
        """(weights, eta, 0.0, arrays) for a compiled segment's steps (in the slots of Anderson's weights,
        safeguard, regularization and arrays; the patience travels in the arrays), or None when unbound."""
        if self._arrays is None:
            return None
        return self._weights, self.eta, 0.0, self._arrays

    def sync_stats(self) -> None:
        """The counts from the kernel's arrays (after steps taken there)."""
        if self._arrays is not None:
            ist = self._arrays.ist
            self.stats["extrapolated"] = int(ist[fast_kernel.EXTRAPOLATED])
            self.stats["restarts"] = int(ist[fast_kernel.RESTARTS])
            self.stats["rejected"] = int(ist[fast_kernel.FAILED])

    def propose(self, s: State, f: State, rho: float, inner) -> State:
        """A plain step in a back-off, the momentum step (A5), or a restart (A6)."""
        if self._arrays is not None:
            return self._propose_kernel(s, f, rho)
        if self._skip > 0:                                                               # backing off: plain
            self._skip -= 1
            return f
        g = _diff(f, s)
        c = w_inner(g, g, rho, inner)                                                    # (A4)
        previous = self._f
        if previous is None or c < self.eta * self._c:
            a_next = (1 + math.sqrt(1 + 4 * self._a ** 2)) / 2
            beta = (self._a - 1) / a_next
            self._a, self._c, self._f = a_next, c, f
            self._momentum = previous is not None and beta != 0
            if not self._momentum:
                return f
            self.stats["extrapolated"] += 1
            self._phase += 1
            return f[0] + beta * (f[0] - previous[0]), f[1] + beta * (f[1] - previous[1])   # (A5)
        self.stats["restarts"] += 1                                                      # (A6)
        if self._phase < self.patience:                                # a failed momentum phase: back off
            self.stats["rejected"] += 1
            self._skip, self._backoff = self._backoff, min(2 * self._backoff, BACKOFF_MAX)
            self._streak = self._streak + 1 if self._phase < fast_kernel.SHORT else 0
            if 0 < self.give_up <= self._streak:                       # momentum never got going: off for good (A7)
                self._skip = fast_kernel.FOREVER
        else:
            self._backoff, self._streak = 1, 0
        back, self._momentum, self._phase, self._a = self._momentum, False, 0, 1.0
        if self._skip > 0:                                             # momentum starts afresh after it
            self._c, self._f = math.inf, None
        if back:                                                       # s_k extrapolated: back to f_{k-1}
            if self._f is not None:
                self._c = self._c / self.eta
            return previous
        if self._f is not None:                                        # s_k plain: keep f_k
            self._c, self._f = c, f
        return f

    def _propose_kernel(self, s: State, f: State, rho: float) -> State:
        """:meth:`propose` by ``admmkit.loop.fast_kernel.fast_update`` on the stacked states (its numpy twin,
        the same bits, where kernels run as Python)."""
        step = fast_kernel.fast_update if compiled_now() else fast_kernel.fast_update_numpy
        out = np.empty_like(f[0]), np.empty_like(f[1])
        arrays = self._arrays
        step(float(rho), self._weights, self.eta, *s, *f, *out, arrays.ist, arrays.ac, arrays.f_prev)
        self.sync_stats()
        return out


ACCELERATORS = {"anderson": Anderson, "fast": FastADMM}


def make_accelerator(acceleration) -> Accelerator | None:
    """None, an :class:`Accelerator`, or a name (``"anderson"``, ``"fast"``) -> an accelerator or None."""
    if acceleration is None or isinstance(acceleration, Accelerator):
        return acceleration
    if isinstance(acceleration, str) and acceleration.strip().lower() in ACCELERATORS:
        return ACCELERATORS[acceleration.strip().lower()]()
    raise ValueError(f"acceleration must be None, 'anderson', 'fast' or an admmkit.loop.acceleration.Accelerator, "
                     f"got {acceleration!r}")


class Acceleration:
    """The loop's side of an accelerator: which vectors are the state, and what a change of rho implies.

    Order "xz" starts an iteration from (z, lam), order "zx" from (A x, lam).
    :meth:`step` takes the vectors before and after an iteration and returns
    the (z, lam, A x) the next iteration starts from.  A change of rho
    changes the map T: the rho event (:class:`admmkit.loop.steps.RhoEvent`) resets
    the accelerator through :meth:`reset` and the plain iterate is kept.
    """

    def __init__(self, accelerator: Accelerator, order: str, inner, weights=None, size: int | None = None):
        self.accelerator, self.inner = accelerator, inner
        self._u = 0 if order == "xz" else 2        # the index of u in (z, lam, Ax)
        if isinstance(accelerator, KernelAccelerator):     # kernel steps for a weighted inner product, else numpy
            accelerator.bind(weights, size)
        accelerator.start()

    def kernel_state(self):
        """What a compiled segment needs to take the accelerator's steps itself, or None (it cannot)."""
        if self._u != 0 or not isinstance(self.accelerator, (Anderson, FastADMM)):
            return None
        return self.accelerator.kernel_state()

    def after_segment(self) -> None:
        """The counts after a segment took steps."""
        self.accelerator.sync_stats()

    def step(self, old: tuple, new: tuple, rho: float) -> tuple:
        """(z, lam, Ax) for the next iteration from those before (``old``) and after (``new``) it, at an
        unchanged rho (a change of rho restarts the accelerator instead: :meth:`reset`)."""
        i = self._u
        u, lam = self.accelerator.propose((old[i], old[1]), (new[i], new[1]), rho, self.inner)
        return (u, lam, new[2]) if i == 0 else (new[0], lam, u)

    def reset(self) -> None:
        """Restart: part of the event of a change of rho (:class:`admmkit.loop.steps.RhoEvent`)."""
        self.accelerator.reset()

    def summary(self) -> dict:
        """The accelerator and its counts (extrapolated, rejected, restarts) for the result."""
        return {"accelerator": repr(self.accelerator), **self.accelerator.stats}
