"""The obstacle's and the contact's pictures read at a glance (#47 item 8): axis labels on every panel, the
adapted mesh coloured by element size with zooms on its finest triangles, the contact set never white."""
import numpy as np
import pytest
from matplotlib.colors import to_rgba

from admmkit import ResidualTolerance, solve
from admmkit.problems.mesh_plot import check_indicators, element_sizes, zoom_windows
from admmkit.problems.obstacle import make_problem, radial
from admmkit.problems.obstacle.estimate import zz_indicators
from admmkit.problems.obstacle.plot import CONTACT_LABEL, adapted_figure, solution_figure


@pytest.fixture(scope="module")
def obstacle():
    """(problem, u, z): the radial scene at h = 1/4 (P1), solved tightly."""
    problem = make_problem(radial(h=1 / 4))
    res = solve(problem, rho=1.0, policy="summable", order="zx", stop=ResidualTolerance(1e-9, 1e-9))
    return problem, res.x, res.z


def panels(fig):
    """The axes of a figure without its colour bars."""
    return [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]


def assert_labelled(fig):
    """Every panel has both axis labels; every colour bar a label."""
    for ax in panels(fig):
        assert ax.get_xlabel() != "" and ax.get_ylabel() != "", ax.get_title()
    for ax in fig.axes:
        if ax.get_label() == "<colorbar>":
            assert ax.get_ylabel() != ""


def contact_patches(ax):
    """The collections of ``ax`` labelled as the contact set."""
    return [c for c in ax.collections if c.get_label().startswith(CONTACT_LABEL)]


def test_solution_figure_labels_and_a_contact_set_that_is_not_white(obstacle):
    import matplotlib.pyplot as plt
    problem, u, z = obstacle
    fig = solution_figure(problem, u, z)
    try:
        assert_labelled(fig)
        section, field = panels(fig)
        (contact,) = contact_patches(field)
        assert len(contact.get_paths()) > 0                       # the radial scene touches: triangles drawn
        for rgba in contact.get_facecolor():
            assert not np.allclose(rgba[:3], 1.0, atol=0.05)      # not white, the reading of a hole
        assert to_rgba(contact.get_edgecolor()[0])[:3] != (1.0, 1.0, 1.0) and contact.get_hatch()
        legend = [t.get_text() for t in field.get_legend().get_texts()]
        assert any(t.startswith("contact set u = psi") for t in legend)
        assert any(t.startswith("contact set u = psi") for t in (x.get_text() for x in section.get_legend().get_texts()))
    finally:
        plt.close(fig)


def test_adapted_figure_colours_by_element_size_and_zooms(obstacle):
    import matplotlib.pyplot as plt
    problem, u, z = obstacle
    fig = adapted_figure(problem, zz_indicators(problem, u), z)
    try:
        assert_labelled(fig)
        mesh, zoom1, eta, zoom2 = panels(fig)
        points = problem.nodes[:problem.mesh.nv]
        shade = mesh.collections[0]
        assert np.allclose(shade.get_array(), np.log10(element_sizes(points, problem.tri)))
        assert any("log10 h_T" in ax.get_ylabel() for ax in fig.axes)                # its colour bar
        width = lambda ax: np.diff(ax.get_xlim())[0]              # noqa: E731
        assert width(zoom2) < width(zoom1) < width(mesh)
        assert contact_patches(eta) and "contact set u = psi" in eta.get_legend().get_texts()[0].get_text()
    finally:
        plt.close(fig)


def test_zoom_windows_centre_on_the_smallest_triangle_inside_the_box():
    points = np.array([[0, 0], [4, 0], [4, 4], [0, 4], [2, 2], [3.9, 3.9], [3.95, 3.9]], dtype=float)
    tri = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [5, 6, 2]])
    h = element_sizes(points, tri)
    assert h[4] == pytest.approx(np.hypot(0.1, 0.1)) and np.argmin(h) == 4
    (cx1, cy1, w1), (cx2, cy2, w2) = zoom_windows(points, tri)
    assert w1 == pytest.approx(0.5) and (cx1, cy1) == pytest.approx((3.5, 3.5))      # moved inside the box
    assert w2 <= w1 / 4 and cx2 + w2 <= 4 and cy2 + w2 <= 4


def test_indicators_of_another_mesh_are_named():
    with pytest.raises(ValueError, match="5 error indicators for a mesh of 6 triangles"):
        check_indicators(np.ones(5), 6)


def test_contact_adapted_figure_labels_and_zooms():
    import matplotlib.pyplot as plt
    from admmkit.problems.contact import example1, solve_scene
    from admmkit.problems.contact.output.plot import adapted_figure as contact_adapted
    from admmkit.problems.contact.solvers.estimate import estimator_indicators
    sol = solve_scene(example1(h=1 / 5), "sadmm", 1e3)
    ops, res = sol.ops, sol.result
    fig = contact_adapted(ops, res.x, res.lam, estimator_indicators(ops, res.x, res.lam), "ex1")
    try:
        assert_labelled(fig)
        assert len(panels(fig)) == 5                              # mesh, two zooms, ZZ, pressure
        assert "x on Gamma_C" in [ax.get_xlabel() for ax in panels(fig)]
    finally:
        plt.close(fig)
