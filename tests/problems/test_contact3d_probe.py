"""bench contact3d's probes run in a child process of their own: that process must find its module."""
from admmkit.benchmarks.contact import contact3d as contact3d_bench


def test_probe_in_subprocess_runs_the_benchmark_module():
    row = contact3d_bench.probe_in_subprocess(1 / 4, "amg", timeout=120)
    assert row["status"] == "ok", row["status"]       # was "failed: ... No module named benchmarks.contact3d"
    assert row["n_free"] == 900 and row["cg_iterations"] >= 1 and row["amg_residual"] < 1e-8
