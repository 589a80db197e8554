"""`admmkit bench policies`: the penalty rules on the finite-element problems (contact, obstacle, Tresca) across rho_0."""
