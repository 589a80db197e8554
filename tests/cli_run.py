"""Running ``admmkit`` in the test process, for the command-line tests."""
from admmkit.cli import main


def run(argv, capsys):
    """(exit code, stdout, stderr) of ``admmkit ARGV``."""
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def one_error_line(err: str) -> str:
    """The single line of an error, and that it is one: no usage block, no traceback, nothing else."""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("admmkit: error: ") and "usage:" not in err and "Traceback" not in err
    return lines[0]
