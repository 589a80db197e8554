"""Benchmarks that users choose penalty rules by: ``admmkit bench precision | stability | paper-compare``.

- :mod:`.sweep`: the resumable parallel runner (one JSON line per finished case);
- :mod:`.methods`: every registered policy in both orders, the paper's names kept;
- :mod:`.scenes`: the discrete problems, their reference solutions and error norms;
- :mod:`.admm_runs`: one ADMM run with a tolerance ladder read off its clock;
- :mod:`.peers`: PDAS, cvxpy + Clarabel, cvxpy + OSQP, OSQP on the same discrete problem;
- :mod:`.precision`, :mod:`.stability`, :mod:`.paper`: the three targets;
- :mod:`.report`: machine and versions, CSV, Markdown, PNG + SVG;
- :mod:`.cli`: the ``admmkit bench`` sub-commands.

Nothing here runs in the unit tests except tiny smoke runs (tests/test_benchmarks.py).
"""
