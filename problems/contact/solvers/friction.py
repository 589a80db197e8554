"""Friction on Gamma_C: the tangential frames, the friction data and the Tresca z-step.

With friction the constraint space carries, at every contact node i, the
normal displacement and the d - 1 tangential ones,

    A u = (B u, T u),   (T u)_i = (t_i^1 . u(x_i), ..., t_i^{d-1} . u(x_i)),

stacked by component: z = (z_n, z_t1[, z_t2]), each block of length n_c, and
the inner product is the lumped mass M_c on every block.  Tresca's law with a
slip bound s_i >= 0 adds j(z) = sum_i mc_i s_i |z_t,i - w_i| to the objective
(w_i the foundation's tangential displacement, ``obstacle_slide``), and the
z-step, the M-weighted prox of I_{z_n <= g} + j, splits node by node into

    z_n,i = min(g_i, v_n,i)                                              (11)
    z_t,i = w_i + max(0, 1 - (s_i/rho) / |v_t,i - w_i|) (v_t,i - w_i)    (11t)

with v = A u + lam/rho: the paper's projection for the normal part and
soft-thresholding (in 3D: shrinking the length of a 2-vector) for the
tangential part.  At a solution lam = (p_n, q) holds the contact pressure
p_n = -sigma_n >= 0 and the tangential traction q = -sigma_t, the force per
unit length the body exerts on the foundation along t, with |q_i| <= s_i and
q_i = s_i (slip direction) where the node slips.  Coulomb's law takes
s = mu p_n (:mod:`admmkit.problems.contact.solvers.coulomb`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the tangential conditions on Gamma_C
TANGENTIAL = ("frictionless", "stick", "tresca", "coulomb")
FRICTIONAL = ("tresca", "coulomb")


@dataclass
class Friction:
    """The friction law at the contact nodes.

    ``law`` "tresca" or "coulomb"; ``s`` the slip bound at the nodes (n_c,)
    (Tresca: given; Coulomb: the current fixed-point value, mu p_n);
    ``mu`` Coulomb's coefficient (None for Tresca); ``slide`` (n_c, d-1) the
    foundation's tangential displacement w (zero unless the scene moves it).
    """

    law: str
    s: np.ndarray
    mu: float | None = None
    slide: np.ndarray | None = None

    def __post_init__(self):
        if self.law not in FRICTIONAL:
            raise ValueError(f"friction law = {self.law!r}; accepted: {', '.join(FRICTIONAL)}")
        self.s = np.asarray(self.s, dtype=float)
        check_slip_bound_values(self.s, "slip_bound")
        if self.mu is not None:
            check_mu(self.mu)


def check_mu(mu) -> float:
    """Coulomb's friction coefficient: a finite number >= 0 (ValueError naming ``mu`` otherwise)."""
    if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not math.isfinite(mu) or mu < 0:
        raise ValueError(f"mu = {mu!r} is outside the accepted range: a finite friction coefficient mu >= 0")
    return float(mu)


def check_slip_bound_values(s: np.ndarray, name: str = "slip_bound") -> None:
    """Slip bound values: finite and >= 0 (ValueError naming ``name`` otherwise)."""
    s = np.asarray(s, dtype=float)
    if not np.all(np.isfinite(s)):
        raise ValueError(f"{name}: not finite at some contact node(s); accepted: finite values s >= 0")
    if np.any(s < 0):
        raise ValueError(f"{name}: negative value {s.min():g}; accepted: a slip bound s >= 0")


def check_friction_fields(tangential: str, slip_bound, mu, points) -> None:
    """Scene-level checks: the law's parameter is given, the other one is not, values in range.

    ``slip_bound`` is a float or a callable f(x, y) (already parsed),
    sampled at ``points`` (a few points of the contact boundary, may be empty).
    """
    if tangential not in TANGENTIAL:
        raise ValueError(f"tangential = {tangential!r}; accepted: {', '.join(TANGENTIAL)}")
    if tangential == "tresca" and slip_bound is None:
        raise ValueError("slip_bound: tangential = 'tresca' needs a slip bound s >= 0 (a number or an expression)")
    if tangential == "coulomb" and mu is None:
        raise ValueError("mu: tangential = 'coulomb' needs a friction coefficient mu >= 0")
    if slip_bound is not None and tangential != "tresca":
        raise ValueError(f"slip_bound is Tresca's friction parameter; it needs tangential = 'tresca', "
                         f"got tangential = {tangential!r}")
    if mu is not None and tangential != "coulomb":
        raise ValueError(f"mu is Coulomb's friction coefficient; it needs tangential = 'coulomb', "
                         f"got tangential = {tangential!r}")
    if mu is not None:
        check_mu(mu)
    if slip_bound is not None:
        values = [slip_bound_at(slip_bound, x, y) for x, y in points] if callable(slip_bound) else [slip_bound]
        check_slip_bound_values(np.array(values, dtype=float))


def slip_bound_at(slip_bound, x: float, y: float) -> float:
    """s(x, y) as a float (ValueError naming slip_bound if the function fails)."""
    if not callable(slip_bound):
        return float(slip_bound)
    try:
        return float(slip_bound(x, y))
    except Exception as err:
        raise ValueError(f"slip_bound: s({x:g}, {y:g}) failed: {err}") from None


def tangent_frames(normals: np.ndarray) -> np.ndarray:
    """Unit tangents (n_c, d-1, d) orthogonal to the unit normals (n_c, d).

    2D: t = (-n_y, n_x) (n turned by +90 degrees: t = (1, 0) for n = (0, -1)).
    3D: t1 = the coordinate axis least aligned with n, made orthogonal to n
    and normalised, t2 = t1 x n (t1 = (1, 0, 0), t2 = (0, 1, 0) for n = (0, 0, -1)).
    """
    normals = np.asarray(normals, dtype=float)
    n_c, d = normals.shape
    if d == 2:
        return np.stack([-normals[:, 1], normals[:, 0]], axis=1)[:, None, :]
    axis = np.eye(3)[np.argmin(np.abs(normals), axis=1)]
    t1 = axis - np.sum(axis * normals, axis=1, keepdims=True) * normals
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(t1, normals)
    return np.stack([t1, t2], axis=1)


def shrink(v_t: np.ndarray, threshold: np.ndarray) -> np.ndarray:
    """Soft-thresholding of the tangential vectors: max(0, 1 - thr/|v|) v, node by node.

    ``v_t`` is (d-1, n_c) (one row per tangential component), ``threshold`` (n_c,).
    """
    length = np.sqrt(np.sum(v_t * v_t, axis=0))
    factor = np.maximum(0.0, 1.0 - threshold / np.maximum(length, 1e-300))
    return v_t * factor


def friction_z_step(v: np.ndarray, g: np.ndarray, s: np.ndarray, rho: float, slide: np.ndarray | None) -> np.ndarray:
    """The z-step (11), (11t) at v = A u + lam/rho (module docstring); a new array."""
    n_c = g.size
    z = np.empty_like(v)
    z[:n_c] = np.minimum(g, v[:n_c])                               # (11): projection onto z_n <= g
    v_t = v[n_c:].reshape(-1, n_c)
    w = 0.0 if slide is None else slide.T
    z[n_c:] = (w + shrink(v_t - w, s / rho)).ravel()               # (11t): prox of s |z_t - w| / rho
    return z


def stick_slip(z: np.ndarray, g: np.ndarray, slide: np.ndarray | None) -> np.ndarray:
    """Zone of each contact node from the last z-step: 0 separated, 1 stick, 2 slip.

    A node is in contact where the z-step put z_n on the obstacle (z_n = g);
    it sticks where the shrink put z_t exactly on the foundation's position
    (|v_t - w| <= s/rho), and slips otherwise.
    """
    n_c = g.size
    z_t = z[n_c:].reshape(-1, n_c) - (0.0 if slide is None else slide.T)
    contact = z[:n_c] >= g
    still = np.all(z_t == 0.0, axis=0)
    return np.where(contact, np.where(still, 1, 2), 0)


def friction_of(scene, xc: np.ndarray) -> Friction | None:
    """The Friction of a scene at its contact nodes xc (None unless tangential is 'tresca' or 'coulomb').

    Works for any scene object with ``tangential``, ``slip_bound``, ``mu`` and
    ``obstacle_slide`` (a number in 2D along t, a pair (w_x, w_y) in 3D).
    """
    if scene.tangential not in FRICTIONAL:
        return None
    d = xc.shape[1]
    slide = np.tile(np.atleast_1d(np.asarray(scene.obstacle_slide, dtype=float)), (len(xc), 1))
    if slide.shape[1] != d - 1:
        raise ValueError(f"obstacle_slide = {scene.obstacle_slide!r}; accepted: {d - 1} number(s) in {d}D")
    if scene.tangential == "tresca":
        s = np.array([slip_bound_at(scene.slip_bound, x[0], x[1]) for x in xc])
        return Friction("tresca", s, slide=slide)
    return Friction("coulomb", np.zeros(len(xc)), mu=check_mu(scene.mu), slide=slide)
