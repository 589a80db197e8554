"""Contact plug-in: elastic contact with a rigid foundation, frictionless or with friction (NGSolve).

    from admmkit.problems.contact import example1, solve_scene
    sol = solve_scene(example1(h=1/40), "sadmm", rho=1e3)
    print(sol.result.summary())

Your own NGSolve mesh, space and forms: ``contact_operators(fes, a, f, contact, gap)``
(problems/contact/model/custom.py), solved the same way.
"""
#: the public names and the modules that define them, imported on first use: ``admmkit solve contact`` from the
#: operator cache imports no NGSolve (model/operator_cache.py), and the package itself does not force it
_NAMES = {"ContactOperators": "model.operators", "assemble": "model.assembly", "contact_operators": "model.custom",
          "METHODS": "solvers.methods", "ContactSolution": "solvers.methods", "method": "solvers.methods",
          "solve_scene": "solvers.methods", "CondensedContact": "solvers.problem", "FullContact": "solvers.problem",
          "contact_problem": "solvers.problem", "Scene": "model.scene", "example1": "model.scene",
          "example2": "model.scene", "load_scene": "model.scene_file"}

__all__ = ["Scene", "example1", "example2", "load_scene", "assemble", "ContactOperators", "contact_problem",
           "FullContact", "CondensedContact", "METHODS", "method", "solve_scene", "ContactSolution",
           "contact_operators"]


def __getattr__(name: str):
    """The public names of the plug-in (``from admmkit.problems.contact import solve_scene``), loaded on first use."""
    if name not in _NAMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib
    value = getattr(importlib.import_module(f"{__name__}.{_NAMES[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names, the ones loaded on first use included."""
    return sorted({*globals(), *_NAMES})
