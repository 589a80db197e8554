"""Every study and sweep of admmkit, a folder per command or subject, with the shared parts written once.

- ``runner``: what every study uses: the resumable sweep (``sweep``: one JSON
  line per finished case, written by the driver alone) with its executors
  (``sweep_local``: local processes; ``sweep_dask``: Dask), the worker side
  (``sweep_worker``), the consolidated table (``sweep_table``), reports and
  figures (``report``), Dolan-Moré profiles (``profiles``), the machine and
  the one timer (``machine``), the options every study command shares
  (``options``), and what a study needs installed and which failed cases are
  the harness's, not the rule's (``harness``);
- ``fixtures``: what the studies of the rules share: the methods (every rule
  in both orders, ``methods``), the problem families with their references
  and peers (``families``, ``references``, ``peers``, ``pdas``), the ADMM
  runs (``admm_runs``);
- ``rules``: ``admmkit bench rules``, every rule (and yours) through every
  family, ranked (``study``: the grid and the summary; ``cases``: how one
  case runs; ``report``: the ranking);
- ``precision``, ``stability``, ``policies``, ``obstacle``: ``bench
  precision`` (work-precision), ``bench stability``, ``bench policies`` (the
  rules on the FE problems), ``bench obstacle`` (the obstacle's rates);
- ``adaptive``: ``bench adaptive`` (adaptive against uniform refinement) and
  ``bench estimators``;
- ``qp``: the Maros-Meszaros study, fidelity to OSQP, agreement with Clarabel;
- ``contact``: the paper's reproduction (``paper``, its published tables in
  ``data/``), speed, scale, 3D, Hertz, friction, the sparse backends;
- ``framework``: the loop's overhead, four problems from the building
  blocks, the executors.

A folder is named as its command is typed.  Each registers its commands (``admmkit bench ...``) in its own small
``cli.py`` with ``runner.options.add_study`` (or ``own_parser`` for a study that parses its own options), found
through the entry points in ``pyproject.toml``.
Dependencies point one way: benchmarks -> problems -> policies -> admmkit.
"""
