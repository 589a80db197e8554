"""The warm start of a refined 2D contact level: the last level's displacement on Gamma_C, carried over.

The meshes are nested, so the last level's u_h lives in the new space, and
on Gamma_C its trace is known exactly from the last level's nodal values:
on each old contact edge [p_a, p_b] the values of A u (the normal
displacement, and the tangential one with friction) are linear (P1) or
quadratic through p_a, the midpoint and p_b (P2) in t, the position along
the chord.  A new contact node is placed on the old edge it lies on (on a
curved boundary the new vertices sit on the curve, a sagitta off the old
chord: the nearest chord that spans it), a clamped end of Gamma_C counts 0.

The condensed mode's x = (s, w) with u = s K^{-1} f + K^{-1} A'w has
A u = s d0 + C w on Gamma_C (``CondensedContact``), so

    w0 = C^{-1} (d - d0),  s = 1

is the new level's field with that trace.  The multiplier stays the old
pressure interpolated along Gamma_C (``adaptive._along_boundary``, the
caller's ``lam0``): the one of stationarity, -w0 / M_c, is a derivative of
the trace and was off by 17-29 % at Hertz's peak pressure when the
balanced stop fired (it controls the displacement's algebraic error, not
the pressure's; P1 to 1e-2, the interpolated one 0.09-1.1 %, as before).
Against the old start (x0 from the interpolated pressure too, w0 = -M_c
lam0) it cut the warm levels' iterations on Hertz P1 to 1e-2 from 32 to 23,
and with -w0 / M_c as the multiplier over four targets each: Example 2 P2
(5e-3 .. 5e-4) 446 -> 110, Example 1 P2 (2e-3 .. 3e-4) 199 -> 91, Example 1
P1 (2e-2 .. 7e-3) 84 -> 55 (docs/contact.md: the study's figures); the
time the same within the noise, the levels' set-up dominates it.
"""
from __future__ import annotations

from dataclasses import dataclass

import ngsolve as ng
import numpy as np
import scipy.linalg as sla
from scipy.spatial import cKDTree


@dataclass
class ContactTrace:
    """A level's displacement on Gamma_C: its contact edges and the values of A u at each edge's nodes."""

    edges: np.ndarray       # (E, 2, 2): p_a, p_b of every contact edge
    values: np.ndarray      # (blocks, E, order + 1): A u at p_a, p_b (and the midpoint, P2), by block of A
    order: int


def contact_edges(mesh: ng.Mesh, contact: str) -> np.ndarray:
    """(E, 2, 2): the end points of every boundary edge of the 2D boundary ``contact``."""
    ends = [[mesh[v].point[:2] for v in el.vertices] for el in mesh.Elements(ng.BND) if el.mat == contact]
    return np.array(ends, dtype=float).reshape(-1, 2, 2)


def contact_trace(problem, u: np.ndarray) -> ContactTrace:
    """The trace A u of a level's displacement ``u`` (free dofs) on Gamma_C, by contact edge (``problem``: the
    level's contact problem, whose A is B, or [B; T] with friction)."""
    ops = problem.ops
    d = (problem.A @ u).reshape(-1, ops.n_c)               # blocks: u.n, then u.t with friction
    edges = contact_edges(ops.mesh, ops.scene.contact)
    points = [edges[:, 0], edges[:, 1]] + ([edges.mean(axis=1)] if ops.scene.order == 2 else [])
    scale = max(float(np.ptp(ops.xc, axis=0).max()), 1.0)
    dist, idx = cKDTree(ops.xc).query(np.stack(points, axis=1).reshape(-1, 2))
    node = np.where(dist <= 1e-10 * scale, idx, -1).reshape(len(edges), len(points))
    values = np.where(node >= 0, d[:, np.maximum(node, 0)], 0.0)      # a clamped end: no contact node, u = 0
    return ContactTrace(edges, values, ops.scene.order)


def trace_at(trace: ContactTrace, xc: np.ndarray) -> np.ndarray:
    """(blocks, len(xc)): the trace at the points ``xc`` of Gamma_C, each on the old chord that spans it."""
    xc = np.asarray(xc, dtype=float)
    if xc.ndim != 2 or xc.shape[1] != 2:
        raise ValueError(f"trace_at: xc must hold one 2D point per row, shape (points, 2); got shape {xc.shape}")
    pa, pb = trace.edges[:, 0], trace.edges[:, 1]
    chord = pb - pa
    t = np.einsum("nek,ek->ne", xc[:, None, :] - pa[None], chord) / np.einsum("ek,ek->e", chord, chord)
    off = np.linalg.norm(xc[:, None, :] - pa[None] - t[..., None] * chord[None], axis=2)
    span = (t >= -1e-9) & (t <= 1 + 1e-9)
    if not span.any(axis=1).all():
        raise ValueError("trace_at: a point of Gamma_C lies on no old contact edge (the meshes are not nested)")
    e = np.argmin(np.where(span, off, np.inf), axis=1)
    t = np.clip(t[np.arange(len(xc)), e], 0.0, 1.0)
    if trace.order == 1:
        basis = np.stack([1 - t, t])
    else:                                                  # Lagrange at t = 0, 1, 1/2
        basis = np.stack([2 * (t - 0.5) * (t - 1), 2 * t * (t - 0.5), -4 * t * (t - 1)])
    return np.sum(trace.values[:, e, :] * basis.T[None], axis=2)


def trace_warm_start(problem, trace: ContactTrace, lam0: np.ndarray) -> dict | None:
    """x0, lam0, z0 of a condensed contact level: x0 the field with the last level's trace on Gamma_C, ``lam0`` the
    given multiplier (the interpolated pressure, module docstring), z0 the z-step of x0; None where a new contact
    node lies on no old edge or C is not positive definite (then the caller starts from the pressure alone)."""
    try:
        d = trace_at(trace, problem.ops.xc).ravel()
        w0 = sla.cho_solve(sla.cho_factor(problem.C), d - problem.d0)
    except (np.linalg.LinAlgError, ValueError):
        return None
    return start_at(problem, np.concatenate(([1.0], w0)), lam0)


def start_at(problem, x0: np.ndarray, lam0: np.ndarray) -> dict:
    """The start of a condensed contact level from x0 and lam0: with z0 the z-step of A x0 (x0 made feasible)."""
    return {"x0": x0, "lam0": lam0, "z0": problem.z_step(problem.apply_A(x0), np.zeros_like(lam0), 1.0, None)}


__all__ = ["ContactTrace", "contact_edges", "contact_trace", "trace_at", "trace_warm_start", "start_at"]
