"""Fixtures shared by the plug-ins' tests."""
import pytest


@pytest.fixture
def level_vtus():
    """A check of the per-level VTU files of an adaptive run: ``check(folder, stem, levels, point_fields)``.

    Every level ``k`` (1-based, ``levels`` as the run's JSON lists them) has
    ``folder/stem_level<k>.vtu`` with its cells, one ZZ indicator per cell and the given point fields.
    """
    import meshio

    def check(folder, stem, levels, point_fields):
        for k, level in enumerate(levels, 1):
            vtu = meshio.read(folder / f"{stem}_level{k}.vtu")
            assert len(vtu.cells[0].data) == level["cells"] == len(vtu.cell_data["zz_indicator"][0])
            assert set(point_fields) <= set(vtu.point_data)
    return check


@pytest.fixture(scope="session")
def contact_tight():
    """``tight(ops)``: the contact operators' exact discrete solution to round-off, a converged Result (SADMM in
    the condensed mode to Boyd residuals 1e-10; 1e-12 meets the round-off floor of some sparse backends)."""
    import admmkit
    from admmkit.problems.contact import solve_scene

    def tight(ops):
        sol = solve_scene(ops, "sadmm", 1e3, mode="condensed", stop=admmkit.ResidualTolerance(1e-10, 1e-10),
                          max_iter=50_000)
        assert sol.result.converged
        return sol.result
    return tight
