"""Contact plug-in: elastic contact with a rigid foundation, frictionless or with friction (NGSolve).

    from admmkit.problems.contact import example1, solve_scene
    sol = solve_scene(example1(h=1/40), "sadmm", rho=1e3)
    print(sol.result.summary())

Your own NGSolve mesh, space and forms: ``contact_operators(fes, a, f, contact, gap)``
(problems/contact/model/custom.py), solved the same way.
"""
from admmkit.problems.contact.model.assembly import ContactOperators, assemble
from admmkit.problems.contact.model.custom import contact_operators
from admmkit.problems.contact.solvers.methods import METHODS, ContactSolution, method, solve_scene
from admmkit.problems.contact.solvers.problem import CondensedContact, FullContact, contact_problem
from admmkit.problems.contact.model.scene import Scene, example1, example2
from admmkit.problems.contact.model.scene_file import load_scene

__all__ = ["Scene", "example1", "example2", "load_scene", "assemble", "ContactOperators", "contact_problem",
           "FullContact", "CondensedContact", "METHODS", "method", "solve_scene", "ContactSolution",
           "contact_operators"]
