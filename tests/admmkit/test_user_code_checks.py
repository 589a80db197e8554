"""User code in the loop is checked where it answers (issue #46 items 2 and 6): a stopping rule, a policy, a
callback and the plug-in's steps that return the wrong thing are stopped at their first answer with one error
naming the class (or callback) and the value; numbers are numbers, not text; a rule loaded from a file cannot
end the program."""
import numpy as np
import pytest

import admmkit
from admmkit import Policy, Problem, RelativeChange, StoppingRule, solve
from admmkit.cli import main


class Obstacle5(Problem):
    """min 1/2 x'Dx - b'x subject to x <= g, five unknowns, every step explicit."""

    n = 5
    d, b, g = np.full(5, 2.0), np.arange(5.0), np.ones(5)

    def x_step(self, z, lam, rho, x):
        return (self.b - lam + rho * z) / (self.d + rho)

    def z_step(self, Ax, lam, rho, z):
        return np.minimum(self.g, Ax + lam / rho)

    def apply_A(self, x):
        return x.copy()

    def adjoint_norm(self, y):
        return float(np.linalg.norm(y))


# ------------------------------------------------------------------------------------ stopping rules
class Answers(StoppingRule):
    """A rule that answers ``answer`` at every record, counting its calls."""

    def __init__(self, answer):
        self.answer, self.calls = answer, 0

    def fired(self, rec):
        self.calls += 1
        return self.answer


@pytest.mark.parametrize("answer", ["always", 42, True, False, 1.0, np.ones(3), ""])
def test_a_rule_that_answers_neither_its_name_nor_a_stop_nor_none_is_refused_at_once(answer):
    rule = Answers(answer)
    with pytest.raises(TypeError, match=r"stopping rule Answers.fired\(\) returned .*it must return the rule's name "
                                        r"'rule' when it fires, an admmkit.Stop .* or None"):
        solve(Obstacle5(), order="zx", stop=rule)
    assert rule.calls == 1                                    # its first answer


@pytest.mark.parametrize("compose", [lambda bad: bad | RelativeChange(1e-300), lambda bad: RelativeChange(1e3) & bad])
def test_a_bad_answer_inside_a_composed_rule_is_refused_too(compose):
    with pytest.raises(TypeError, match=r"stopping rule Answers.fired\(\) returned int 42"):
        solve(Obstacle5(), order="zx", stop=compose(Answers(42)))


def test_a_rule_that_returns_its_name_or_none_still_stops_the_run():
    class Tenth(StoppingRule):
        name = "tenth"

        def fired(self, rec):
            return self.name if rec.k == 9 else None
    res = solve(Obstacle5(), order="zx", stop=Tenth() | RelativeChange(1e-300))
    assert res.iterations == 10 and res.stopped_by == "tenth"


# ------------------------------------------------------------------------------------ policies
class Returns(Policy):
    """A rule that returns ``value`` at every record, counting its calls."""

    def __init__(self, value):
        self.value, self.calls = value, 0

    def update(self, rec):
        self.calls += 1
        return self.value


@pytest.mark.parametrize("value, error, needle", [
    ("1", TypeError, r"returned str '1'"), (None, TypeError, "returned NoneType None"),
    (True, TypeError, "returned bool True"), (np.ones(5), TypeError, r"returned ndarray of shape \(5,\)"),
    ([2.0], TypeError, r"returned list of shape \(1,\)"), (np.nan, ValueError, "returned rho = nan"),
    (np.inf, ValueError, "returned rho = inf"), (0.0, ValueError, "returned rho = 0.0"),
    (-1, ValueError, "returned rho = -1"),
])
def test_a_policy_that_returns_no_penalty_is_stopped_at_its_first_answer(value, error, needle):
    rule = Returns(value)
    with pytest.raises(error, match=rf"policy Returns.update\(\) {needle}.* at iteration 1"):
        solve(Obstacle5(), order="zx", policy=rule, stop=RelativeChange(1e-300), max_iter=50)
    assert rule.calls == 1


@pytest.mark.parametrize("value", [2, np.float32(2.0), np.array(2.0)])
def test_a_policy_may_return_any_kind_of_number(value):
    res = solve(Obstacle5(), order="zx", policy=Returns(value), stop=RelativeChange(1e-300), max_iter=20)
    assert res.status.value == "max_iter" and res.rho == 2.0


def test_a_policy_fed_a_blown_up_record_ends_the_run_as_diverged():
    class Blows(Obstacle5):
        def x_step(self, z, lam, rho, x):
            return 1e200 * (x + 1.0)

    class Product(Policy):
        def update(self, rec):
            return rec.rho * (1.0 + 0.0 * rec.primal_residual)      # NaN once ||r|| is inf
    res = solve(Blows(), order="zx", policy=Product(), check_every=50, max_iter=50)
    assert res.status.value == "diverged" and "non-finite iterate" in res.message


# ------------------------------------------------------------------------------------ callbacks
@pytest.mark.parametrize("answer", [np.ones(3), [1], "stop", 1, 0])
def test_a_callback_that_returns_neither_none_nor_a_bool_is_named(answer):
    def watch(rec):
        return answer
    with pytest.raises(TypeError, match=r"callback .*watch returned .*a callback returns None \(go on\) or a bool"):
        solve(Obstacle5(), order="zx", callback=watch)


@pytest.mark.parametrize("answer", [True, np.bool_(True)])
def test_a_callback_stops_the_run_with_a_bool(answer):
    res = solve(Obstacle5(), order="zx", callback=lambda rec: answer if rec.k == 3 else None)
    assert res.status.value == "stopped" and res.iterations == 4


# ------------------------------------------------------------------------------------ the plug-in's steps
class Strict(Obstacle5):
    """Its steps assert that they are given arrays: a bad return must be stopped before the next step sees it."""

    bad = {}

    def x_step(self, z, lam, rho, x):
        assert isinstance(z, np.ndarray) and z.shape == (5,)
        return self.bad.get("x_step", super().x_step)(z, lam, rho, x)

    def z_step(self, Ax, lam, rho, z):
        assert isinstance(Ax, np.ndarray) and Ax.shape == (5,)
        return self.bad.get("z_step", super().z_step)(Ax, lam, rho, z)

    def apply_A(self, x):
        assert isinstance(x, np.ndarray) and x.shape == (5,)
        return self.bad.get("apply_A", super().apply_A)(x)


def _bad(step, returned):
    problem = Strict()
    calls = []

    def answer(*args):
        calls.append(step)
        if step == "apply_A" and len(calls) == 1:      # A x0 at the start is right; the first iteration's is not
            return args[0].copy()
        return returned
    problem.bad = {step: answer}
    return problem


@pytest.mark.parametrize("order", ["xz", "zx"])
@pytest.mark.parametrize("step, returned, error, needle", [
    ("x_step", 1.0, TypeError, r"Strict.x_step\(\) returned float; it must return a numpy array of shape \(5,\)"),
    ("x_step", None, TypeError, r"Strict.x_step\(\) returned NoneType; it must return a numpy array of shape \(5,\)"),
    ("z_step", np.ones(3), ValueError, r"Strict.z_step\(\) returned an array of shape \(3,\); it must have shape \(5,\)"),
    ("z_step", np.ones((5, 1)), ValueError, r"Strict.z_step\(\) returned an array of shape \(5, 1\); it must have"),
    ("apply_A", np.ones(4), ValueError, r"Strict.apply_A\(\) returned an array of shape \(4,\); it must have shape "
                                        r"\(5,\) \(the shape of z\)"),
])
def test_a_step_that_returns_the_wrong_thing_is_named_before_anything_uses_it(order, step, returned, error, needle):
    with pytest.raises(error, match=needle):
        solve(_bad(step, returned), order=order)


def test_a_wrong_apply_A_at_the_start_is_named():
    problem = Strict()
    problem.bad = {"apply_A": lambda x: np.ones(4)}
    problem.initial_point = lambda: (np.zeros(5), np.zeros(5), np.zeros(5))
    with pytest.raises(ValueError, match=r"Strict.apply_A\(\) returned an array of shape \(4,\); it must have shape"):
        solve(problem)


@pytest.mark.skipif(not admmkit.loop.segments.AVAILABLE, reason="segments need numba")
def test_the_first_iteration_runs_in_python_before_any_segment():
    class Compiled(Obstacle5):
        """A plug-in with a compiled segment, whose own x-step is wrong."""

        segments = []

        def x_step(self, z, lam, rho, x):
            return 0.0

        def segment(self, x, z, lam, Ax, rho, alpha, order, count):
            self.segments.append(count)
            return None
    problem = Compiled()
    with pytest.raises(TypeError, match=r"Compiled.x_step\(\) returned float"):
        solve(problem, order="xz", check_every=25)
    assert problem.segments == []                     # the segment, which bypasses x_step, never ran first


# ------------------------------------------------------------------------------------ warm starts and numbers
def test_a_nan_warm_start_is_refused_naming_it():
    first = solve(Obstacle5(), order="zx", max_iter=5)
    first.x_iterate = np.full(5, np.nan)
    with pytest.raises(ValueError, match="warm_start.x_iterate must be finite, got 5 NaN or infinite entries"):
        solve(Obstacle5(), order="zx", warm_start=first)
    with pytest.raises(ValueError, match="lam0 must be finite"):
        solve(Obstacle5(), order="zx", lam0=[0, 0, np.nan, 0, 0])


@pytest.mark.parametrize("name, value", [("rho", "1"), ("time_limit", "1"), ("alpha", "1.5"), ("rho", [1.0]),
                                         ("alpha", True)])
def test_text_is_not_a_number(name, value):
    with pytest.raises(TypeError, match=rf"{name} must be a number \(.*\), got {type(value).__name__}"):
        solve(Obstacle5(), order="zx", **{name: value})


# ------------------------------------------------------------------------------------ rules loaded from files
RULE = """from admmkit import Policy

class Good(Policy):
    def update(self, rec):
        return rec.rho
"""


@pytest.mark.parametrize("source, needle", [
    ("import sys\nsys.exit(0)\n", r"importing .*exit0.py failed: SystemExit: sys.exit\(0\)"),
    ("raise KeyError('boom')\n", r"importing .*exit0.py failed: KeyError: 'boom'"),
    ("import sys\nfrom admmkit import Policy\nclass X(Policy):\n    def __init__(self):\n        sys.exit(3)\n"
     "    def update(self, rec):\n        return rec.rho\n", r"X\(\) raised SystemExit: sys.exit\(3\)"),
])
def test_a_rule_file_that_raises_or_exits_is_one_error_line(tmp_path, capsys, source, needle):
    (tmp_path / "exit0.py").write_text(source)
    assert main(["solve", "qp", "--random", "5", "5", "--policy", str(tmp_path / "exit0.py") + ":X"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("admmkit: error: --policy: ") and len(err.strip().splitlines()) == 1
    assert __import__("re").search(needle, err)


@pytest.mark.parametrize("command", [["solve", "contact", "--h", "1/8"], ["solve", "obstacle", "--h", "1/8"]])
def test_a_rule_file_works_wherever_policy_is(tmp_path, capsys, command):
    (tmp_path / "rules.py").write_text(RULE)
    code = main([*command, "--policy", f"{tmp_path / 'rules.py'}:Good", "--quiet", "--tol", "1e-5",
                 "--max-iter", "30"])
    out = capsys.readouterr()
    assert code in (0, 1) and "unknown method" not in out.err
    assert "policy=Good()" in out.out and "iterations   30" in out.out
