"""The benchmark charts read at a glance (#47 item 8): bench adaptive's error charts in a grid with axis labels,
drawn again from a committed adaptive.csv; bench rules' profile panels say why they are empty."""
import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

from admmkit.benchmarks.rules import report as rank_report
from admmkit.benchmarks.adaptive.charts import error_figure, levels_figure, read_rows, redraw
from admmkit.benchmarks.runner.report import write_csv

STUDY = Path(__file__).resolve().parents[2] / "docs" / "results" / "adaptive_study" / "adaptive.csv"


def visible(fig):
    """The panels that are drawn (spare panels are switched off)."""
    return [ax for ax in fig.axes if ax.axison]


def test_adaptive_error_charts_are_a_labelled_grid():
    rows = read_rows(STUDY)
    fig = error_figure(rows)
    try:
        shape = fig.axes[0].get_subplotspec().get_gridspec().get_geometry()
        assert shape[0] > 1 and shape[1] <= 4                      # a grid, not one row of 14 panels
        drawn = visible(fig)
        assert len(drawn) == 14
        for ax in drawn:
            assert ax.get_xlabel() != "" and ax.get_ylabel() != "" and ax.get_title() != ""
        legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
        assert len(legends) == 1                                   # one legend for every panel
        names = [t.get_text() for t in legends[0].get_texts()]
        assert names[0].startswith("adaptive") and "common error of the table" in names
    finally:
        plt.close(fig)


def test_adaptive_levels_chart_has_axis_labels():
    fig = levels_figure(read_rows(STUDY))
    try:
        for ax in fig.axes:
            assert ax.get_xlabel() == "unknowns" and ax.get_ylabel() != ""
    finally:
        plt.close(fig)


def test_read_rows_gives_back_numbers_and_nan(tmp_path):
    write_csv(tmp_path / "adaptive.csv", [{"scene": "ex1", "order": 2, "true_error": 1.5e-3, "a_error": math.nan},
                                          {"scene": "ex1", "order": 2, "true_error": None, "a_error": 0.25}])
    a, b = read_rows(tmp_path / "adaptive.csv")
    assert a["scene"] == "ex1" and a["order"] == 2 and a["true_error"] == 1.5e-3 and math.isnan(a["a_error"])
    assert math.isnan(b["true_error"]) and b["a_error"] == 0.25


@pytest.mark.study   # the whole chart redraw
def test_redraw_writes_both_charts_from_the_csv(tmp_path):
    (tmp_path / "adaptive.csv").write_text(STUDY.read_text())
    assert [p.name for p in redraw(tmp_path)] == ["adaptive.png", "adaptive_levels.png"]
    assert all((tmp_path / n).stat().st_size > 10_000 for n in ("adaptive.png", "adaptive_levels.png"))


def run(family, problem, config, solved, iterations=10):
    return {"family": family, "problem": problem, "config": config, "solved": solved,
            "status": "solved" if solved else "CaseTimeout", "iterations": iterations if solved else math.nan,
            "seconds": 0.1 * iterations if solved else math.nan}


def test_profile_panels_say_why_they_are_empty():
    configs = ["a", "b"]
    rows = [run("qp", f"p{i}", c, True, 10 + i + (c == "b")) for i in range(3) for c in configs]
    rows += [run("obstacle", f"p{i}", c, False) for i in range(2) for c in configs]
    families = ["qp", "obstacle", "friction", "framework", "stability"]     # the last three without a run
    fig = rank_report.profiles_figure(rows, families, configs, "iterations")
    try:
        shape = fig.axes[0].get_subplotspec().get_gridspec().get_geometry()
        assert shape[0] > 1 and shape[1] <= 4
        notes = {ax.get_title().split(":")[0]: [t.get_text() for t in ax.texts] for ax in visible(fig)}
        assert notes["qp"] == []
        assert "no run of this family solved" in notes["obstacle"][0] and "4 runs failed (CaseTimeout)" in \
            notes["obstacle"][0]
        for family in ("friction", "framework", "stability"):
            assert "no run of this family in this study" in notes[family][0]
        overall = [ax for ax in visible(fig) if ax.get_title().startswith("overall")][0]
        assert "4 without a solved run count as 0" in overall.get_title()
        for ax in visible(fig):
            assert ax.get_xlabel() != "" and ax.get_ylabel() != ""
    finally:
        plt.close(fig)


def test_rank_note_helper():
    table = np.full((2, 2), np.inf)
    assert rank_report.empty_note([], table).startswith("no run of this family in this study")
    assert rank_report.empty_note([run("qp", "p", "a", False)], table).startswith("no run of this family solved")
    table[0, 0] = 3.0
    assert rank_report.empty_note([run("qp", "p", "a", True)], table) is None
