"""The README's code blocks run and say what the README claims."""
import re
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_examples_run():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) >= 2
    ns: dict = {}
    for block in blocks:
        exec(compile(block, str(README), "exec"), ns)
    result = ns["result"]  # the last one: the user's Halve policy
    assert result.converged and np.allclose(result.x, [0, 0.5, 1, 1, 1], atol=1e-4)
    rho = result.history["rho"]
    assert rho[0] == 64 and (len(rho) < 11 or rho[10] == 32)


def test_readme_commands_exist():
    from admmkit.cli import build_parser

    text = README.read_text()
    assert "pip install . && admmkit demo" in text
    test_command = re.search(r'^    (pip install "\.\[test\]" && python -m pytest -q.*)$', text, flags=re.M).group(1)
    ci = (README.parent / ".ci" / "run").read_text()
    assert f"python -m {test_command}\n" in ci          # CI runs the README's test command as written
    parser = build_parser()
    for line in re.findall(r"^    admmkit (solve .*)$", text, flags=re.M):
        args = parser.parse_args(line.split("#")[0].split())   # a trailing comment says how it ends
        assert args.func
