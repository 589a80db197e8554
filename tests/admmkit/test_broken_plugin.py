"""A plug-in command whose module does not load (a syntax error, a missing import) breaks only that command."""
import sys
from importlib.metadata import EntryPoint

import admmkit.cli as cli
import admmkit.cli.host as host


def test_a_plug_in_with_a_syntax_error_breaks_only_its_own_command(tmp_path, monkeypatch, capsys):
    (tmp_path / "broken_plugin.py").write_text("def register(subparsers:\n    pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("broken_plugin", None)
    found = dict(cli.commands())
    found["solve.broken"] = EntryPoint("solve.broken", "broken_plugin:register", cli.GROUP)
    monkeypatch.setattr(host, "commands", lambda: found)
    assert cli.main(["solve", "broken", "--x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("admmkit: error: ") and "could not be loaded: SyntaxError" in err[0]
    assert cli.main(["solve", "qp", "--random", "3", "3", "-q"]) in (0, 1)      # the others still work
