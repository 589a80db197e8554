"""Sweeps of every penalty rule: work-precision, stability, the rules on the finite-element problems, the obstacle's rates."""
