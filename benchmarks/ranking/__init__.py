"""The ranking of every penalty rule through every family (``admmkit bench rules``): the grid, the case runner, the summary."""
