"""The options of an FE plug-in with error estimates: the balanced stop and adaptive refinement.

``admmkit solve obstacle`` and ``admmkit solve contact`` register them with
:func:`add_adaptive_options`, refuse the loop's options without ``--target-error``
with :func:`check_adaptive_flags` and read them with :func:`adaptive_options`.
"""
from __future__ import annotations

import argparse

from ..fe.balanced_stop import GAMMA
from .options import positive_float


def add_adaptive_options(parser: argparse.ArgumentParser, *, max_levels: int = 20, gamma: float = GAMMA,
                         default_stop: bool = False) -> None:
    """``--balance``, ``--target-error``, ``--theta``, ``--max-levels``, ``--max-unknowns``, ``--estimator`` of an
    FE plug-in with error estimates (read by :func:`adaptive_options` and :func:`estimator_name`); ``gamma``: the
    plug-in's default, ``default_stop``: whether the balanced stop is its default without --tol / --eps-abs."""
    parser.add_argument("--balance", type=positive_float, default=None, metavar="GAMMA",
                        help="stop when a guaranteed bound of the algebraic error is below GAMMA x the estimated "
                             "discretisation error, 0 < GAMMA <= 1 (instead of --tol / --eps-abs; with --target-error"
                             f"{', and without --tol / --eps-abs' if default_stop else ''}, "
                             f"GAMMA is {gamma:g} unless given)")
    parser.add_argument("--target-error", type=positive_float, default=None, metavar="E",
                        help="refine adaptively from --h until the estimated relative energy error is <= E, "
                             "0 < E < 1 (--estimator, Doerfler marking, each level warm-started, stopped balanced)")
    parser.add_argument("--theta", type=positive_float, default=None,
                        help="Doerfler marking share with --target-error, 0 < theta < 1 (default 0.5)")
    parser.add_argument("--max-levels", type=int, default=None,
                        help=f"level cap of --target-error (default {max_levels})")
    parser.add_argument("--max-unknowns", type=int, default=None,
                        help="unknowns cap of --target-error (default 2e6)")
    # left None when not given, so that check_adaptive_flags sees them given without --target-error
    parser.set_defaults(loop_defaults={"theta": 0.5, "max_levels": max_levels, "max_unknowns": 2_000_000})
    parser.add_argument("--estimator", default="zz", metavar="zz|residual",
                        help="the discretisation error estimate that --target-error marks by and the balanced stop "
                             "compares with: zz (gradient recovery, default) or residual (residual-type)")


#: the values of ``--estimator``
ESTIMATORS = ("zz", "residual")


def estimator_name(args) -> str:
    """``--estimator``, checked: ValueError naming the option and the accepted values."""
    name = getattr(args, "estimator", "zz")
    if name not in ESTIMATORS:
        raise ValueError(f"--estimator = {name!r} is unknown; accepted: {', '.join(ESTIMATORS)}")
    return name


def balance_gamma(args, default: float | None) -> float | None:
    """gamma of the balanced stop: --balance, else ``default`` when neither --tol nor --eps-abs is given (None
    when one is); ValueError naming --balance for a value outside (0, 1] or beside --tol / --eps-abs."""
    other = args.tol is not None or args.eps_abs is not None
    if args.balance is None:
        return None if other else default
    if other:
        raise ValueError("--balance cannot be combined with --tol or --eps-abs: give one stop")
    if not 0 < args.balance <= 1:
        raise ValueError(f"--balance = {args.balance:g} is outside the accepted range (0, 1]")
    return args.balance


def balance_line(stop, norm: str) -> str:
    """The summary line of a balanced stop: the bound and the estimate it compared last (ZZ unless the stop's
    ``estimator`` says otherwise), and gamma."""
    which = "residual" if getattr(stop, "estimator", "zz") == "residual" else "ZZ"
    return (f"balance      algebraic error <= {stop.algebraic:.3e} (guaranteed bound, {norm})   "
            f"discretisation error ~ {stop.discretisation:.3e} ({which} estimate)   gamma {stop.gamma:g}")


#: the adaptive loop's options, which only --target-error reads
LOOP_FLAGS = {"theta": "--theta", "max_levels": "--max-levels", "max_unknowns": "--max-unknowns"}


def check_adaptive_flags(args) -> None:
    """Refuse --theta, --max-levels and --max-unknowns without --target-error (they would be ignored)."""
    if getattr(args, "target_error", None) is not None:
        return
    given = [flag for dest, flag in LOOP_FLAGS.items() if getattr(args, dest, None) is not None]
    if given:
        raise ValueError(f"{', '.join(given)} {'needs' if len(given) == 1 else 'need'} --target-error (the adaptive "
                         f"loop's options; a uniform solve has no levels to mark or cap)")


def adaptive_options(args, gamma: float = GAMMA) -> dict:
    """The adaptive loop's keywords from :func:`add_adaptive_options` (gamma: the plug-in's default ``gamma``,
    admmkit.fe.balanced_stop.GAMMA unless given, or --balance; the estimator; the loop's options not given take
    the plug-in's defaults); ValueError naming the option and its range, and refusing --tol / --eps-abs
    beside them."""
    defaults = getattr(args, "loop_defaults", None) or {"theta": 0.5, "max_levels": 20, "max_unknowns": 2_000_000}
    for dest, value in defaults.items():
        if getattr(args, dest, None) is None:
            setattr(args, dest, value)
    if args.tol is not None or args.eps_abs is not None:
        raise ValueError("--target-error stops every level balanced (--balance); it cannot be combined with "
                         "--tol or --eps-abs")
    gamma = balance_gamma(args, gamma)
    for flag, value, ok, accepted in [("--target-error", args.target_error, 0 < args.target_error < 1, "(0, 1)"),
                                      ("--theta", args.theta, 0 < args.theta < 1, "(0, 1)"),
                                      ("--max-levels", args.max_levels, args.max_levels >= 1, "an integer >= 1"),
                                      ("--max-unknowns", args.max_unknowns, args.max_unknowns >= 1,
                                       "an integer >= 1")]:
        if not ok:
            raise ValueError(f"{flag} = {value:g} is outside the accepted range {accepted}")
    return {"target": args.target_error, "theta": args.theta, "gamma": gamma, "max_levels": args.max_levels,
            "max_unknowns": args.max_unknowns, "estimator": estimator_name(args)}
