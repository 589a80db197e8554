"""Contact plug-in: 2D plane-strain frictionless contact with a rigid foundation (NGSolve).

    from problems.contact import example1, solve_scene
    sol = solve_scene(example1(h=1/40), "sadmm", rho=1e3)
    print(sol.result.summary())
"""
from .assembly import ContactOperators, assemble
from .methods import METHODS, ContactSolution, method, solve_scene
from .problem import CondensedContact, FullContact, contact_problem
from .scene import Scene, example1, example2, load_scene

__all__ = ["Scene", "example1", "example2", "load_scene", "assemble", "ContactOperators", "contact_problem",
           "FullContact", "CondensedContact", "METHODS", "method", "solve_scene", "ContactSolution"]
