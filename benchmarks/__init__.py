"""Every study and sweep of admmkit, one small module each, with the shared parts written once.

Shared parts:

- ``sweep``: the resumable parallel runner (one JSON line per finished case);
- ``report``: machine and versions, CSV, Markdown tables, labels, figures;
- ``machine``: the machine, the libraries and the commit behind every figure;
- ``methods``: every registered rule in both orders, the paper's names kept;
- ``families``: the problem families (contact, obstacle, QP) as discrete
  problems with their reference solutions and error norms;
- ``peers`` and ``pdas``: the solvers compared (PDAS, cvxpy + Clarabel,
  cvxpy + OSQP, OSQP) on the same discrete problem;
- ``admm_runs``: one ADMM run with a tolerance ladder read off its clock;
- ``cli``: every study's command (``admmkit bench ...``, ``admmkit reproduce paper``).

Studies: ``paper`` (+ ``paper_tables``, the reproduction), ``paper_compare``,
``precision``, ``stability``, ``policies_fe``, ``maros_meszaros``,
``contact_speed``, ``scale`` (+ ``scale_runs``), ``amg_crossover``,
``contact3d``, ``hertz``, ``obstacle_rates``, ``linsolve_backends``.

Dependencies point one way: benchmarks -> problems -> policies -> admmkit.
"""
