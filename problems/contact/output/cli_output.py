"""What ``admmkit solve contact`` prints and writes besides the shared summary: the contact and friction
lines, the CSV table of Gamma_C, and the checks of the friction options (``--tangential``, ``--mu``,
``--slip-bound``) against the scene.

The files themselves are written by :mod:`admmkit.problems.contact.output.export` (VTU, JSON) and
:func:`admmkit.cli.output.write_result_csv`, whole or not at all.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from admmkit.problems.contact.solvers.friction import FRICTIONAL, TANGENTIAL


# ---------------------------------------------------------------- the friction options
def parse_mu(text: str) -> float:
    """``--mu``: a finite number >= 0 (ValueError naming ``--mu`` otherwise)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise ValueError(f"--mu {text}: expected Coulomb's friction coefficient, a finite number mu >= 0")
    return value


def parse_slip_bound(text: str):
    """``--slip-bound``: a number >= 0 or an expression in x, y (its values are checked by the scene)."""
    from admmkit.problems.expressions import expression
    try:
        value = float(text)
    except ValueError:
        try:
            return expression(text)                     # an expression: the scene samples it along Gamma_C
        except ValueError as err:
            raise ValueError(f"--slip-bound {text}: {err}") from None
    if not (math.isfinite(value) and value >= 0):
        raise ValueError(f"--slip-bound {text}: expected Tresca's slip bound, a finite number s >= 0 "
                         f"or an expression in x, y")
    return value


def friction_changes(scene, tangential: str | None, mu: str | None, slip_bound: str | None) -> dict:
    """The scene fields that ``--tangential``, ``--mu`` and ``--slip-bound`` change (ValueError naming the
    option when a value is out of range, given for the wrong model, or missing for the chosen one)."""
    model = tangential or scene.tangential
    if model not in TANGENTIAL:
        raise ValueError(f"--tangential {model}: accepted: {', '.join(TANGENTIAL)}")
    source = f"--tangential {model}" if tangential else f"the scene's tangential = {model!r}"
    if mu is not None and model != "coulomb":
        raise ValueError(f"--mu is Coulomb's friction coefficient; it needs --tangential coulomb ({source})")
    if slip_bound is not None and model != "tresca":
        raise ValueError(f"--slip-bound is Tresca's slip bound; it needs --tangential tresca ({source})")
    changes: dict = {"tangential": model}
    changes["mu"] = parse_mu(mu) if mu is not None else (scene.mu if model == "coulomb" else None)
    changes["slip_bound"] = (parse_slip_bound(slip_bound) if slip_bound is not None
                             else scene.slip_bound if model == "tresca" else None)
    if model == "coulomb" and changes["mu"] is None:
        raise ValueError("--tangential coulomb needs --mu MU (the scene has no mu)")
    if model == "tresca" and changes["slip_bound"] is None:
        raise ValueError("--tangential tresca needs --slip-bound S (the scene has no slip_bound)")
    if model not in FRICTIONAL:                          # the foundation's slide acts only with friction
        slide = scene.obstacle_slide
        changes["obstacle_slide"] = 0.0 if np.ndim(slide) == 0 else tuple(0.0 for _ in slide)
    return changes


def apply_friction_options(scene, args):
    """The scene with the friction options of ``args`` applied (unchanged when none is given)."""
    if args.tangential is None and args.mu is None and args.slip_bound is None:
        return scene
    changes = friction_changes(scene, args.tangential, args.mu, args.slip_bound)
    try:
        return dataclasses.replace(scene, **changes)
    except ValueError as err:
        text = str(err)
        option = (f"--slip-bound {args.slip_bound}" if args.slip_bound is not None and text.startswith("slip_bound")
                  else f"--mu {args.mu}" if args.mu is not None and text.startswith("mu")
                  else f"--tangential {changes['tangential']}")
        raise ValueError(f"{option}: {err}") from None


# ---------------------------------------------------------------- lines and tables
def friction_line(sol, fields: dict) -> str | None:
    """``friction     coulomb (mu 0.3): tangential force ...   stick nodes ..   slip nodes ..`` (None if frictionless)."""
    ops = sol.ops
    if ops.friction is None:
        return None
    law = ops.friction.law + (f" (mu {ops.friction.mu:g})" if ops.friction.mu is not None else "")
    q = np.asarray(fields["tangential_traction"]).reshape(ops.n_c, -1)
    force = ops.mc @ q
    shown = f"{force[0]:.6g}" if force.size == 1 else "(" + ", ".join(f"{v:.6g}" for v in force) + ")"
    zones = np.bincount(fields["stick_slip_zone"], minlength=3)
    return (f"friction     {law}: tangential force {shown}   stick nodes {zones[1]}   slip nodes {zones[2]}   "
            f"separated {zones[0]}   max |slip| {np.abs(np.asarray(fields['slip'])).max(initial=0.0):.4e}")


def csv_columns(sol, fields: dict) -> dict:
    """The ``--csv`` table, one row per contact node: coordinates, normal quantities and, with friction, the
    tangential traction ``q`` and ``slip`` (2D; ``q_1, q_2, slip_1, slip_2`` in 3D), the slip bound ``s``
    and the ``zone`` (0 separated, 1 stick, 2 slip)."""
    ops, r = sol.ops, sol.result
    columns = {"x": ops.xc[:, 0], "y": ops.xc[:, 1]}
    if ops.xc.shape[1] == 3:
        columns["z"] = ops.xc[:, 2]
    columns |= {"u_n": fields["normal_displacement"], "g": fields["initial_gap"], "gap": fields["gap"],
                "lam": fields["contact_pressure"], "p": r.z[:ops.n_c], "active": fields["contact_status"]}
    if ops.friction is not None:
        for name, key in (("q", "tangential_traction"), ("slip", "slip")):
            values = np.asarray(fields[key]).reshape(ops.n_c, -1)
            columns |= ({name: values[:, 0]} if values.shape[1] == 1 else
                        {f"{name}_{j + 1}": values[:, j] for j in range(values.shape[1])})
        columns |= {"s": fields["slip_bound"], "zone": fields["stick_slip_zone"]}
    return columns
