"""Every study and sweep of admmkit, by subject, with the shared parts written once.

- ``runner``: what every study uses: the resumable sweep (``sweep``: one JSON
  line per finished case, written by the driver alone) with its executors
  (``sweep_local``: local processes; ``sweep_dask``: Dask), the worker side
  (``sweep_worker``), the consolidated table (``sweep_table``), reports and
  figures (``report``), Dolan-Moré profiles (``profiles``), the machine and
  the one timer (``machine``), the options every study command shares
  (``options``), and what a study needs installed and which failed cases are
  the harness's, not the rule's (``harness``);
- ``rules``: every rule swept: the methods and problem families with their
  references and peers (``methods``, ``families``, ``references``, ``peers``,
  ``pdas``), work-precision (``precision``), stability (``stability``), the
  rules on the FE problems (``policies_fe``), the obstacle's rates;
- ``qp``: the Maros-Meszaros study, fidelity to OSQP, agreement with Clarabel;
- ``contact``: the paper's reproduction (``paper``, its published tables in
  ``data/``), speed, scale, 3D, Hertz, friction, the sparse backends;
- ``framework``: the loop's overhead, four problems from the building
  blocks, the executors;
- ``ranking``: ``admmkit bench rules``, every rule (and yours) through every
  family, ranked (``study``: the grid; ``cases``: how one case runs;
  ``report``: the summary).

Each subject registers its commands (``admmkit bench ...``) in its own small
``cli.py``, found through the entry points in ``pyproject.toml``.
Dependencies point one way: benchmarks -> problems -> policies -> admmkit.
"""
