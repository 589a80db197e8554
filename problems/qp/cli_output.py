"""What ``admmkit solve qp`` prints and writes beyond the common summary: the termination test, the
infeasibility certificate, the neutral criteria, and JSON/CSV that carry them (admmkit/cli/output.py writes)."""
from __future__ import annotations

import dataclasses
import json

import numpy as np

from admmkit.cli.output import jsonable, number, provenance, result_record, write_result_csv
from admmkit.io import write_text

from .infeasibility import check_dual_certificate, check_primal_certificate


def certificate_summary(qp, result) -> dict | None:
    """The certificate's kind and the measures that make it one (None if the run declared no infeasibility).

    Primal (I1): y with S(y) < 0 and A'y = 0; dual (I2): dx with q'dx < 0, P dx = 0, A dx in the recession cone.
    """
    cert, termination = getattr(result, "certificate", None), getattr(result, "termination", None) or ""
    if cert is None or "infeasible" not in termination:
        return None
    if termination.startswith("primal"):
        return {"kind": "primal", "length": len(cert), **check_primal_certificate(qp, cert)}
    return {"kind": "dual", "length": len(cert), **check_dual_certificate(qp, cert)}


def qp_lines(result, certificate: dict | None, preset: str) -> list[str]:
    """Lines after the common summary: termination, certificate, neutral criteria, polish, one line per warning (rows
    or columns whose scale makes a tolerance vacuous: ``QPResult.warnings``)."""
    termination = getattr(result, "termination", None)
    if preset == "osqp":
        s = result.settings
        test = (f"OSQP's test (R1)-(R3), eps_abs {s.eps_abs:g}, eps_rel {s.eps_rel:g}, "
                f"eps_prim_inf {s.eps_prim_inf:g}, eps_dual_inf {s.eps_dual_inf:g}, every {s.check_every} iterations")
        lines = [f"termination  {termination or 'none fired'}  ({test})"]
    else:
        lines = [f"termination  {result.stopped_by or 'none fired'}  (textbook loop: no infeasibility test)"]
    if certificate is not None:
        measures = "   ".join(f"{k} {number(v)}" for k, v in certificate.items() if k not in ("kind", "length"))
        what = "y with S(y) < 0, A'y = 0" if certificate["kind"] == "primal" else "dx with q'dx < 0, P dx = 0"
        lines.append(f"certificate  {certificate['kind']} infeasibility ({what}): {measures}")
    if result.neutral is not None:
        n = result.neutral
        lines.append(f"neutral      primal {n['primal']:.3e}   dual {n['dual']:.3e}   gap {n['gap']:.3e}"
                     "   (qpbenchmark: inf-norms, absolute)")
    if getattr(result, "polish", None) is not None:
        p = result.polish
        lines.append(f"polish       {p.get('status')}" + (f"  ({p['reason']})" if p.get("reason") else ""))
    lines += [f"warning      {text}" for text in getattr(result, "warnings", None) or ()]
    return lines


def qp_record(result, certificate: dict | None, preset: str) -> dict:
    """:func:`admmkit.cli.output.result_record` plus termination, neutral, OSQP residuals, polish, certificate and
    warnings."""
    settings = getattr(result, "settings", None)
    return result_record(result) | jsonable({
        "preset": preset, "termination": getattr(result, "termination", None) if preset == "osqp" else result.stopped_by,
        "neutral": result.neutral, "residuals": getattr(result, "residuals", None),
        "polish": getattr(result, "polish", None), "certificate": certificate,
        "warnings": list(getattr(result, "warnings", None) or ()),
        "settings": dataclasses.asdict(settings) if settings is not None else None})


def write_qp_json(path, result, args, *, problem: dict, certificate: dict | None, preset: str) -> object:
    """JSON of a QP run: provenance, problem, result (:func:`qp_record`), arrays (x, z, lam, certificate)."""
    arrays = {"x": result.x, "z": result.z, "lam": result.lam}
    if certificate is not None:
        arrays["certificate"] = result.certificate
    data = {"provenance": provenance(args), "problem": jsonable(problem), "result": qp_record(result, certificate, preset),
            "arrays": jsonable(arrays)}
    return write_text(path, json.dumps(data, indent=1) + "\n")


def write_qp_csv(path, qp, result, certificate: dict | None, preset: str) -> object:
    """One row per variable (kind x) and per row of A (kind row); the run's status, termination and neutral
    residuals repeated on every row; ``certificate`` the primal (rows) or dual (variables) certificate, else empty."""
    n, m = qp.n, qp.m
    nan_n, nan_m = np.full(n, np.nan), np.full(m, np.nan)
    cert = np.r_[nan_n, nan_m]
    if certificate is not None:
        cert = np.r_[nan_n, result.certificate] if certificate["kind"] == "primal" else np.r_[result.certificate, nan_m]
    neutral = result.neutral or {"primal": np.nan, "dual": np.nan, "gap": np.nan}
    termination = (result.termination if preset == "osqp" else result.stopped_by) or ""
    columns = {"kind": ["x"] * n + ["row"] * m, "index": np.r_[np.arange(n), np.arange(m)],
               "x": np.r_[result.x, nan_m], "z": np.r_[nan_n, result.z], "lam": np.r_[nan_n, result.lam],
               "l": np.r_[nan_n, qp.l], "u": np.r_[nan_n, qp.u], "certificate": cert,
               "status": [result.status.value] * (n + m), "termination": [termination] * (n + m),
               "neutral_primal": np.full(n + m, neutral["primal"]), "neutral_dual": np.full(n + m, neutral["dual"]),
               "neutral_gap": np.full(n + m, neutral["gap"])}
    return write_result_csv(path, columns)
