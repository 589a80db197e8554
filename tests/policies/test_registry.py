"""One name per rule: the entry-point group ``admmkit.policies`` of pyproject.toml is the only place a built-in
rule is named; its file, class and name agree with docs/policies.md's table; nothing is imported for a side effect."""
from __future__ import annotations

import ast
import re
import subprocess
import sys
import tomllib
import warnings
from pathlib import Path

import pytest

import admmkit

ROOT = Path(__file__).resolve().parents[2]
GROUP = "admmkit.policies"


def declared_in_pyproject() -> dict[str, str]:
    """``{name: "admmkit.policies.<file>:<Class>"}`` from pyproject.toml (the source, not the install)."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return data["project"]["entry-points"][GROUP]


def policy_classes_in(path: Path) -> list[str]:
    """The classes a rule file defines that are ``Policy`` subclasses (directly, or through another rule)."""
    import importlib

    from admmkit import Policy
    tree = ast.parse(path.read_text(encoding="utf-8"))
    module = importlib.import_module(f"admmkit.policies.{path.stem}")
    return [node.name for node in tree.body if isinstance(node, ast.ClassDef)
            and isinstance(getattr(module, node.name, None), type) and issubclass(getattr(module, node.name), Policy)]


def docs_table() -> dict[str, tuple[str, str]]:
    """``{name: (file, Class)}`` from the table of docs/policies.md."""
    rows = re.findall(r"^\| `(\w+)` \| `(\w+\.py)` \| `(\w+)` \|", (ROOT / "docs" / "policies.md").read_text(
        encoding="utf-8"), flags=re.M)
    return {name: (file, cls) for name, file, cls in rows}


def test_every_declared_rule_points_at_a_policy_class_in_its_own_file():
    for name, target in declared_in_pyproject().items():
        module, cls = target.split(":")
        assert module.startswith("admmkit.policies."), target
        path = ROOT / "policies" / (module.removeprefix("admmkit.policies.") + ".py")
        assert cls in policy_classes_in(path), f"{name}: {path.name} defines no Policy subclass {cls}"


def test_every_rule_file_is_declared_once():
    declared = {tuple(t.split(":")) for t in declared_in_pyproject().values()}
    for path in sorted((ROOT / "policies").glob("*.py")):
        for cls in policy_classes_in(path):
            assert (f"admmkit.policies.{path.stem}", cls) in declared, \
                f"{path.name}: {cls} has no line in pyproject.toml's [project.entry-points.\"{GROUP}\"]"


def test_docs_table_names_every_rule_with_its_file_and_class():
    declared = {name: (t.split(":")[0].removeprefix("admmkit.policies.") + ".py", t.split(":")[1])
                for name, t in declared_in_pyproject().items()}
    assert docs_table() == declared


def test_file_and_name_agree_but_where_the_docs_say_why():
    text = (ROOT / "docs" / "policies.md").read_text(encoding="utf-8")
    for name, (file, cls) in docs_table().items():
        if file != f"{name}.py":
            assert f"`{name}`'s file is `{file}`" in text, f"{name}: docs/policies.md does not say why {file}"


def test_no_rule_registers_itself_by_decorator():
    for path in (ROOT / "policies").glob("*.py"):
        assert "register_policy" not in path.read_text(encoding="utf-8"), path.name


def test_a_name_works_in_a_fresh_process_without_importing_the_rules():
    code = ("import sys, admmkit; p = admmkit.make_policy('wohlberg'); "
            "print(type(p).__name__, sorted(m for m in sys.modules if m.startswith('admmkit.policies.') and '._' not in m))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["Wohlberg", "['admmkit.policies.wohlberg']"]


def test_the_package_imports_no_rule_and_exports_every_class():
    code = ("import sys, admmkit.policies as P; "
            "print(sorted(m for m in sys.modules if m.startswith('admmkit.policies.') and '._' not in m)); "
            "print(P.Summable.__name__)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[:2] == ["[]", "Summable"]


def test_builtin_names_are_the_declared_ones():
    from admmkit import policies
    assert set(policies.builtin_rules()) == set(declared_in_pyproject()) <= set(admmkit.policy_names())
    for name, (module, cls) in policies.builtin_rules().items():
        assert getattr(policies, cls) is type(admmkit.make_policy(name))


def test_the_old_class_name_still_works_with_a_deprecation_warning():
    from admmkit import policies
    with pytest.warns(DeprecationWarning, match="AADMM"):
        old = policies.Spectral
    assert old is policies.AADMM
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert type(admmkit.make_policy("aadmm")) is policies.AADMM


def test_an_unknown_class_is_an_attribute_error():
    from admmkit import policies
    with pytest.raises(AttributeError, match="NoSuchRule"):
        policies.NoSuchRule


def test_a_solve_reads_the_entry_points_once_per_process(monkeypatch):
    """The registry is read once: a QP solve after the first scans no installed package's entry points (a scan
    per solve made a small QP's whole solve 70 ms instead of 3)."""
    import numpy as np
    import scipy.sparse as sp

    import admmkit.policy
    from admmkit.problems.qp import QP, solve_qp
    qp = QP(sp.csc_matrix(np.eye(2)), np.array([1.0, -1.0]), sp.csc_matrix(np.eye(2)), -np.ones(2), np.ones(2))
    solve_qp(qp, compiled=False)
    scans = []
    real = admmkit.policy.declared_rules
    monkeypatch.setattr(admmkit.policy, "declared_rules", lambda: scans.append(True) or real())
    for _ in range(2):
        assert solve_qp(qp, compiled=False).converged
    assert scans == []


def test_a_builtin_rule_by_name_scans_no_other_package(monkeypatch):
    """``make_policy("summable")`` (every ``solve contact`` names SADMM's rule) reads admmkit's own distribution,
    not every installed package's entry points (20-30 ms a scan, twice per process before; issue #49)."""
    import admmkit.policy
    scans = []
    real = admmkit.policy.declared_rules
    monkeypatch.setattr(admmkit.policy, "declared_rules", lambda: scans.append(True) or real())
    monkeypatch.delitem(admmkit.policy._REGISTRY, "summable", raising=False)
    if not admmkit.policy.own_rules():
        pytest.skip("admmkit is not installed as a distribution here")
    assert type(admmkit.make_policy("summable")).__name__ == "Summable"
    assert scans == []
    with pytest.raises(ValueError):                    # a name nobody declares: then every package is searched
        admmkit.make_policy("no_such_rule_anywhere")
    assert scans
