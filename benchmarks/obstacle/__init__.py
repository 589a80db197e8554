"""`admmkit bench obstacle`: the obstacle's convergence rates against the radial exact solution, and its rho_0 sweep."""
