"""Studies of the QP plug-in: the rules on Maros-Meszaros, fidelity to OSQP 1.x, agreement with Clarabel."""
