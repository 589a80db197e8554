"""``python -m admmkit ...``: the ``admmkit`` command, for environments whose scripts folder is not on PATH."""
import sys

from admmkit.cli import main

if __name__ == "__main__":
    sys.exit(main())
