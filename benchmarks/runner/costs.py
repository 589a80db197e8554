"""What each study costs on the project machine (2 cores): the one place that says it.

A study's ``--help`` ends its description with ``typical: TEXT`` (:func:`typical`), and a study whose
default run takes more than about 30 s announces it on stderr before any work (:func:`announce`):

    bench contact: about 4 min (245 s), peak memory not recorded, on 2 cores (docs/results/contact_speed.md)

Both read :data:`COSTS`.  The figures come from the committed results (``docs/results/``),
docs/benchmarks.md and docs/scale.md; where none was measured the text says "minutes" and "peak memory not
recorded" rather than a guess.
"""
from __future__ import annotations

import sys
from typing import NamedTuple


class Cost(NamedTuple):
    """``text``: time and peak memory on 2 cores, with where they were measured; ``long``: the default run
    takes more than about 30 s (then it is announced)."""

    text: str
    long: bool = True


#: the peak memory of a study nobody measured
UNRECORDED = "peak memory not recorded"

#: {command: Cost} of every study (``admmkit bench NAME``, ``admmkit reproduce paper``)
COSTS = {
    "reproduce paper": Cost("about 15-40 s (14.6 s in docs/results/paper, 37 s measured from outside on 28 Nov) and "
                            "0.4 GB peak on 2 cores", long=True),
    # benchmarks/contact
    "bench paper-compare": Cost(f"about 7 min with --workers 1 --repeats 5, {UNRECORDED}, on 2 cores "
                                "(docs/benchmarks.md); --quick a minute"),
    "bench contact": Cost("about 4-7 min (245 s in docs/results/contact_speed.md, 7 min 14 s measured from outside on "
                          "28 Nov) and 10.2 GB peak (28 Nov) on 2 cores"),
    "bench contact-schur": Cost(f"about 9 min with --repeats 5 (542 s), less with the default 3, {UNRECORDED}, "
                                "on 2 cores (docs/results/contact_schur)"),
    "bench hertz": Cost(f"minutes, {UNRECORDED}"),
    "bench scale": Cost("about 2 min (104 s) and 2.4 GB peak at the largest size, 1e6 unknowns, on 2 cores "
                        "(docs/results/scale); --quick seconds"),
    "bench amg-crossover": Cost("tens of minutes and 6.4 GB peak (the full mode at 1e6 unknowns) on 2 cores "
                                "(docs/scale.md); --quick a minute"),
    "bench contact3d": Cost("several minutes and 6.2 GB peak (SADMM in the full mode at 1.35e5 unknowns; the run "
                            "at h = 1/32 alone ~15 s and 1.4 GB) on 2 cores (docs/scale.md, "
                            "docs/results/scale/contact3d.md); --growth-only about 80 s and 4 GB peak "
                            "(docs/results/scale/contact3d_growth.md); --quick a minute"),
    "bench friction": Cost(f"about 90 s (92 s), {UNRECORDED}, on 2 cores (docs/results/friction)"),
    "bench linsolve": Cost(f"minutes to tens of minutes up to 1e6 unknowns (--max-n for less), {UNRECORDED}"),
    # benchmarks/framework
    "bench executors": Cost(f"about 10 min: two rounds of three executors, ~90 s each, {UNRECORDED}, on 2 cores "
                            "(docs/benchmarks.md)"),
    "bench loop-overhead": Cost(f"minutes, {UNRECORDED}"),
    "bench four-problems": Cost(f"minutes, {UNRECORDED}"),
    "bench split-speed": Cost(f"about 10 s plus start-up (the timings took 7 s), {UNRECORDED}, on 2 cores "
                              "(docs/results/split_speed)", long=False),
    "bench first-call": Cost(f"minutes, {UNRECORDED}"),
    # benchmarks/rules, precision, stability, policies, obstacle, adaptive
    "bench precision": Cost(f"about 70 min (316 cases), {UNRECORDED}, on 2 cores (docs/benchmarks.md); "
                            "--quick minutes"),
    "bench stability": Cost(f"about 45 min (1376 cases), {UNRECORDED}, on 2 cores (docs/benchmarks.md); "
                            "--quick minutes"),
    "bench policies": Cost(f"minutes (126 cases of a sparser grid took ~90 s, docs/benchmarks.md), {UNRECORDED}"),
    "bench obstacle": Cost(f"minutes, {UNRECORDED}"),
    "bench rules": Cost(f"about 13 min (757 s), {UNRECORDED}, on 2 cores (docs/results/rules_full); --quick ~90 s "
                        "(docs/results/rules_quick)"),
    "bench estimators": Cost(f"minutes, {UNRECORDED}; --quick less"),
    "bench adaptive": Cost("tens of minutes and more than 24 GB peak with the Hertz scenes (killed for memory at "
                           "24.3 GB on 29 November; refused where less than 25 GB is available: --scenes without "
                           "hertz for less); --quick minutes"),
    # benchmarks/qp
    "bench qp": Cost(f"hours for the whole Maros-Meszaros set (5440 cases; resumable with --resume), less with "
                     f"--problems, {UNRECORDED}"),
    "bench qp-fidelity": Cost(f"about 1 min (50 s), up to ~8 min with every rule, {UNRECORDED}, on 2 cores "
                              "(docs/results/qp_fidelity)"),
    "bench qp-agreement": Cost(f"about 11 min (658 s), {UNRECORDED}, on 2 cores (docs/results/qp_agreement)"),
    "bench qp-speed": Cost(f"tens of minutes (77 problems, two accuracies, best of 3), {UNRECORDED}, on 2 cores "
                           "(docs/results/qp_speed)"),
    "bench anderson-cost": Cost(f"about 50 s (seven problems, best of 5, 10,000 fixed-work iterations), "
                                f"{UNRECORDED}, on 2 cores (docs/results/anderson_cost)"),
}


def typical(command: str) -> str:
    """``\\n\\ntypical: TEXT.`` for the end of ``command``'s description (before its ``needs:``)."""
    return f"\n\ntypical: {COSTS[command].text}."


def announce(command: str) -> None:
    """One line on stderr, ``COMMAND: TEXT``, if ``command``'s default run takes more than about 30 s."""
    cost = COSTS.get(command)
    if cost is not None and cost.long:
        print(f"{command}: {cost.text}", file=sys.stderr, flush=True)
