"""Helpers shared by the sweep tests."""
import json
from pathlib import Path

import pytest


def _ids_in_file(path):
    """The ids of the whole lines of a results file, repeats kept (torn lines do not parse)."""
    ids = []
    for line in Path(path).read_text().splitlines():
        try:
            ids.append(json.loads(line)["id"])
        except (json.JSONDecodeError, KeyError, TypeError):
            pass
    return ids


@pytest.fixture
def ids_in_file():
    """The function reading a results file's ids (repeats kept), for tests that count every line."""
    return _ids_in_file
