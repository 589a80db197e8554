"""Results in a notebook (issue #18): History.to_pandas(), concise reprs and HTML tables."""
import re
import sys

import numpy as np
import pytest

import admmkit
from admmkit.loop.history import COLUMNS
from admmkit.problems.contact import example1, solve_scene


@pytest.fixture
def result(vector_problem):
    return admmkit.solve(vector_problem, rho=1.0, max_iter=200)


def test_to_pandas_equals_the_columns(result):
    pd = pytest.importorskip("pandas")   # in the test extra, so CI has it
    frame = result.history.to_pandas()
    assert isinstance(frame, pd.DataFrame) and frame.index.name == "k"
    assert list(frame.columns) == [c for c in COLUMNS if c != "k"] and len(frame) == result.iterations
    cols = result.history.as_dict()
    assert np.array_equal(frame.index.to_numpy(), cols["k"])
    for name in ("rho", "primal_residual", "rho_changed"):
        assert np.array_equal(frame[name].to_numpy(), cols[name], equal_nan=name != "rho_changed")


def test_to_pandas_without_pandas_says_how_to_install_it(result, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)          # import pandas -> ImportError
    with pytest.raises(ImportError, match="pip install pandas"):
        result.history.to_pandas()


def test_history_repr_is_one_line_without_an_address(result):
    text = repr(result.history)
    assert "\n" not in text and " at 0x" not in text and len(text) < 200
    assert text.startswith(f"History(mode='lean', {result.iterations} iterations")
    assert repr(admmkit.History()) == "History(mode='full', 0 iterations)"


def test_history_html_shows_first_and_last_rows(result):
    html = result.history._repr_html_()
    assert html.count("<tr>") == 1 + 6 + 1                   # header, 3 + 3 rows, the "..." row
    assert f"... {result.iterations - 6} rows ..." in html and "primal_residual" in html


def test_result_repr_and_html(result):
    assert repr(result) == (f"Result(status='{result.status.value}', iterations={result.iterations}, "
                            f"stopped_by={result.stopped_by!r})")
    html = result._repr_html_()
    assert html.startswith("<div><b>admmkit.Result</b>") and result.status.value in html
    assert f"<td style='text-align:left'>{result.iterations}</td>" in html


def test_contact_solution_repr_is_short():
    sol = solve_scene(example1(1 / 10), "sadmm", 1e3)
    text = repr(sol)
    assert "\n" not in text and len(text) < 250 and "array(" not in text
    assert re.search(r"n_free=440, n_c=20, mode='condensed', status='converged', iterations=\d+, active_nodes=\d+", text)
    assert f"active_nodes={sol.result.kkt['active_nodes']}" in text
    html = sol._repr_html_()
    assert "<b>ContactSolution</b>" in html and "admmkit.Result" in html and len(html) < 3000
