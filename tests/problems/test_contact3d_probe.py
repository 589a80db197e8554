"""bench contact3d's probes run in a child process of their own: that process must find its module."""
from admmkit.benchmarks.contact import contact3d as contact3d_bench


def test_probe_in_subprocess_runs_the_benchmark_module():
    row = contact3d_bench.probe_in_subprocess(1 / 4, "amg", timeout=120)
    assert row["status"] == "ok", row["status"]       # was "failed: ... No module named benchmarks.contact3d"
    assert row["n_free"] == 900 and row["cg_iterations"] >= 1 and row["amg_residual"] < 1e-8


def test_growth_chart_shows_the_targets_inside_its_frame(tmp_path, monkeypatch):
    # the 60 s line sat on the frame's top edge when the largest run came close to it
    import matplotlib
    matplotlib.use("Agg")
    saved, save = [], contact3d_bench.save_figure
    monkeypatch.setattr(contact3d_bench, "save_figure", lambda fig, path: saved.append(fig) or save(fig, path))
    rows = [{"status": "converged", "n_free": n, "wall_s": t, "cpu_s": t, "solve_s": 0.9 * t,
             "peak_rss_bytes": 4e3 * n, "estimate_bytes": 4.4e3 * n}
            for n, t in ((4e4, 2.5), (3e5, 14.6), (1e6, 59.0))]
    paths = contact3d_bench.figure_growth(rows, tmp_path / "growth")
    assert [p.suffix for p in paths] == [".png", ".svg"] and all(p.stat().st_size > 0 for p in paths)
    time_axes, memory_axes = saved[0].axes[:2]
    assert time_axes.get_ylim()[1] >= 1.5 * contact3d_bench.TARGET_SECONDS
    assert memory_axes.get_ylim()[1] >= 1.5 * contact3d_bench.TARGET_BYTES / 1e9
