"""A rule from anywhere (#26 item 1): by entry point, as module:Class, or as path/to/file.py:Class."""
import textwrap

import numpy as np
import pytest

import admmkit
from admmkit import policy as policy_module
from admmkit.cli import main

HALVE = textwrap.dedent('''
    import admmkit

    class Halve(admmkit.Policy):
        """Halve rho every 10 iterations."""
        def update(self, rec):
            return rec.rho / 2 if rec.k % 10 == 9 else rec.rho

    class NotARule:
        pass

    class NoUpdate(admmkit.Policy):
        pass
''')


@pytest.fixture
def rule_file(tmp_path):
    path = tmp_path / "my_rules.py"
    path.write_text(HALVE)
    return path


def test_a_rule_in_a_file_runs_by_its_path(rule_file, vector_problem):
    res = admmkit.solve(vector_problem, rho=64.0, policy=f"{rule_file}:Halve", max_iter=25)
    rho = res.history["rho"]
    assert rho[0] == 64 and rho[10] == 32 and rho[20] == 16
    assert type(admmkit.make_policy(f"{rule_file}:Halve")).__name__ == "Halve"


def test_a_rule_in_a_module_runs_by_module_and_class(vector_problem):
    res = admmkit.solve(vector_problem, policy="admmkit.policies.summable:Summable", order="zx")
    ref = admmkit.solve(vector_problem, policy="summable", order="zx")
    assert res.iterations == ref.iterations and np.array_equal(res.x, ref.x)


@pytest.mark.parametrize("spec,message", [
    ("{dir}/missing.py:Halve", "no such file"),
    ("{file}:Missing", "has no 'Missing'"),
    ("{file}:NotARule", "not a subclass of admmkit.Policy"),
    ("{file}:NoUpdate", "does not implement update"),
    ("{dir}/broken.py:Halve", "importing .* failed: ZeroDivisionError"),
    ("no_such_module_xyz:Rule", "failed to import"),
])
def test_a_rule_that_does_not_load_is_named_with_what_is_wrong(spec, message, rule_file, tmp_path):
    (tmp_path / "broken.py").write_text("x = 1 / 0\n")
    spec = spec.format(dir=tmp_path, file=rule_file)
    with pytest.raises((ValueError, TypeError), match=message) as info:
        admmkit.make_policy(spec)
    assert spec.split(":")[0].split("/")[-1] in str(info.value)


class FakeEntryPoint:
    def __init__(self, name, value, target):
        self.name, self.value, self._target = name, value, target

    def load(self):
        if isinstance(self._target, Exception):
            raise self._target
        return self._target


def test_a_rule_declared_by_an_installed_package_is_found_by_name(monkeypatch, rule_file, vector_problem):
    cls = policy_module.load_spec(f"{rule_file}:Halve")
    import importlib.metadata
    real = importlib.metadata.entry_points          # admmkit.policy.declared_rules imports it when it runs

    def fake(group):
        found = list(real(group=group))
        if group == policy_module.GROUP:
            found += [FakeEntryPoint("halving", "their_pkg.rules:Halve", cls),
                      FakeEntryPoint("broken_rule", "their_pkg.rules:Broken", ImportError("no module their_pkg"))]
        return found

    monkeypatch.setattr(importlib.metadata, "entry_points", fake)
    assert {"halving", "broken_rule", "summable"} <= set(admmkit.policy_names())
    res = admmkit.solve(vector_problem, rho=8.0, policy="halving", max_iter=12)
    assert res.history["rho"][10] == 4
    with pytest.raises(ValueError, match="broken_rule.*their_pkg.rules:Broken.*no module their_pkg"):
        admmkit.make_policy("broken_rule")
    policy_module._REGISTRY.pop("halving", None)


def test_the_command_line_takes_a_rule_file(rule_file, capsys):
    code = main(["solve", "qp", "--random", "20", "30", "--preset", "textbook", "--policy", f"{rule_file}:Halve",
                 "--order", "zx", "--eps-abs", "1e-6", "-q"])
    out = capsys.readouterr().out
    assert code in (0, 1) and "Halve" in out


def test_the_command_line_names_a_bad_rule_in_one_line(rule_file, capsys):
    code = main(["solve", "qp", "--random", "20", "30", "--policy", f"{rule_file}:NotARule", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--policy" in err[0] and "NotARule" in err[0]


def test_a_rule_file_is_ranked_by_a_sweep_on_local_processes(rule_file, tmp_path):
    """The sweep's worker processes load the file by its absolute path; results as in one process."""
    from admmkit.benchmarks.policies.study import run
    spec = policy_module.canonical_spec(f"{rule_file}:Halve")
    kwargs = dict(rules=(spec, "summable"), quick=True, progress=False, max_iter=3000, problems=("obstacle",))
    two = run(tmp_path / "two", workers=2, **kwargs)
    one = run(tmp_path / "one", workers=1, **kwargs)
    rows = lambda res: sorted((r["rule"], r["order"], r["rho0"], r["iterations"]) for rs, _ in res.values() for r in rs)  # noqa: E731
    assert rows(two) == rows(one) and any(r[0] == spec for r in rows(two))


def test_bench_policies_refuses_a_bad_rule_before_any_case(rule_file, tmp_path, capsys):
    code = main(["bench", "policies", "--quick", "--out", str(tmp_path / "o"), "--rules", f"summable,{rule_file}:Nope",
                 "-q"])
    assert code == 2 and "Nope" in capsys.readouterr().err
    assert not (tmp_path / "o" / "results.jsonl").exists()


@pytest.mark.study   # a Dask LocalCluster end to end
def test_a_rule_file_gives_the_same_results_on_a_dask_local_cluster(rule_file, tmp_path):
    pytest.importorskip("distributed")
    from admmkit.benchmarks.policies.study import run
    from admmkit.benchmarks.runner.sweep import Executor
    spec = policy_module.canonical_spec(f"{rule_file}:Halve")
    kwargs = dict(rules=(spec,), quick=True, progress=False, max_iter=3000, problems=("obstacle",))
    local = run(tmp_path / "local", workers=1, **kwargs)
    dask = run(tmp_path / "dask", executor=Executor(dask_workers=2), **kwargs)
    rows = lambda res: sorted((r["order"], r["rho0"], r["iterations"], r["rho_final"]) for rs, _ in res.values() for r in rs)  # noqa: E731
    assert rows(dask) == rows(local) and len(rows(local)) == 6
