"""Obstacle plug-in: -Delta u = f, u >= psi (or <= psi), u = u_D, P1 or P2 with NGSolve.

Split with z = u on the free nodes in the lumped mass inner product; the
z-step is the pointwise projection onto the obstacle constraint.
"""
from .discrete import make_problem
from .p2 import ObstacleProblemP2
from .problem import ObstacleProblem, build_mesh, solve_with_cvxpy
from .scene import A_STAR, SCENES, Scene, pyramid, radial, radial_exact, radial_psi, scene
from .scene_file import known_scenes, load_scene

__all__ = ["Scene", "ObstacleProblem", "ObstacleProblemP2", "make_problem", "build_mesh", "solve_with_cvxpy", "scene", "radial",
           "pyramid", "radial_exact", "radial_psi", "SCENES", "A_STAR", "load_scene", "known_scenes"]
