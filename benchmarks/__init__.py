"""Every study and sweep of admmkit, one small module each, with the shared parts written once.

Shared parts:

- ``sweep``: the resumable runner (one JSON line per finished case, written by
  the driver alone), with its executors ``sweep_local`` (local processes) and
  ``sweep_dask`` (Dask), the worker side ``sweep_worker`` and the consolidated
  table ``sweep_table`` (Parquet or CSV);
- ``report``: machine and versions, CSV, Markdown tables, labels, figures;
- ``machine``: the machine, the libraries and the commit behind every figure, and the one timer;
- ``methods``: every registered rule in both orders, the paper's names kept;
- ``families``: the problem families (contact, obstacle, QP) as discrete
  problems with their reference solutions and error norms;
- ``peers`` and ``pdas``: the solvers compared (PDAS, cvxpy + Clarabel,
  cvxpy + OSQP, OSQP) on the same discrete problem;
- ``admm_runs``: one ADMM run with a tolerance ladder read off its clock;
- ``cli``: every study's command (``admmkit bench ...``, ``admmkit reproduce paper``).

Studies: ``paper`` (+ ``paper_tables``, the reproduction), ``paper_compare``,
``precision``, ``stability``, ``policies_fe``, ``maros_meszaros`` (+
``maros_meszaros_report``), ``qp_fidelity``, ``qp_agreement``, ``contact_speed``,
``scale`` (+ ``scale_runs``), ``amg_crossover``, ``contact3d``, ``hertz``,
``obstacle_rates``, ``friction_validation``, ``loop_overhead``, ``four_problems``,
``executors``, ``linsolve_backends``.

Dependencies point one way: benchmarks -> problems -> policies -> admmkit.
"""
