"""`admmkit bench adaptive` and `admmkit bench estimators`: adaptive against uniform refinement, and the error estimators."""
