"""`admmkit bench rules`: every rule (and yours) through every family, ranked: its grid (study.py), case runner (cases.py) and summary (report.py)."""
