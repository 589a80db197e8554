"""Every study and sweep of admmkit, one small module each, with the shared parts written once.

Shared parts:

- :mod:`.sweep`: the resumable parallel runner (one JSON line per finished case);
- :mod:`.report`: machine and versions, CSV, Markdown tables, labels, figures;
- :mod:`.machine`: the machine, the libraries and the commit behind every figure;
- :mod:`.methods`: every registered rule in both orders, the paper's names kept;
- :mod:`.families`: the problem families (contact, obstacle, QP) as discrete
  problems with their reference solutions and error norms;
- :mod:`.peers` and :mod:`.pdas`: the solvers compared (PDAS, cvxpy + Clarabel,
  cvxpy + OSQP, OSQP) on the same discrete problem;
- :mod:`.admm_runs`: one ADMM run with a tolerance ladder read off its clock;
- :mod:`.cli`: every study's command (``admmkit bench ...``, ``admmkit reproduce paper``).

Studies: :mod:`.paper` (+ :mod:`.paper_tables`, the reproduction), :mod:`.paper_compare`,
:mod:`.precision`, :mod:`.stability`, :mod:`.policies_fe`, :mod:`.maros_meszaros`,
:mod:`.contact_speed`, :mod:`.scale` (+ :mod:`.scale_runs`), :mod:`.amg_crossover`,
:mod:`.contact3d`, :mod:`.hertz`, :mod:`.obstacle_rates`, :mod:`.linsolve_backends`.

Dependencies point one way: benchmarks -> problems -> policies -> admmkit.
"""
