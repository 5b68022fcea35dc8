"""While an exercise is graded, the exercises below it answer as the reference (answers.py).

A notebook whose ``inner`` is wrong in every way (it raises, returns garbage, draws
from the generator differently) has an ``outer`` that calls it; graded as ``outer``,
its results must be exactly those of the same ``outer`` run in this process with the
reference ``inner``: values, exceptions, generator draws, in-place changes and
aliasing. The oracle is always that in-process run.
"""

from __future__ import annotations

import types

import numpy as np
import pytest

from robolab.grading.labs import discover_labs
from robolab.grading.loading.notebook import lab_exercises
from robolab.grading.running.answers import Answers, DependencyCycle, dependency_table
from robolab.grading.running.proxy import StudentCodeError, open_submission
from tests.grading import TEST_LIMITS, write_notebook


# The reference, living in the grader only.
def inner(x, rng=None):
    """Reference: 2x, plus a normal draw when a generator is given; refuses negative x."""
    x = np.asarray(x, dtype=float)
    if np.any(x < 0):
        raise ValueError(f"x must be >= 0, got {x}")
    return 2.0 * x + (rng.normal(size=x.shape) if rng is not None else 0.0)


def bump(a):
    """Reference: adds 1 in place and returns its argument."""
    a += 1.0
    return a


REFERENCE = types.SimpleNamespace(inner=inner, bump=bump)

STUDENT_INNER = """\
import numpy as np

def inner(x, rng=None):
    raise RuntimeError("the student's inner must never run while outer is graded")

def bump(a):
    return a * 0.0
"""

OUTER = """\
import numpy as np
alias = inner

def _helper(x):
    return alias(x)

def outer(x, rng):
    first = inner(x, rng)               # positional generator
    second = inner(x, rng=rng)          # keyword generator
    return np.concatenate([first, second, [rng.random()], _helper(x)])

def outer_catches(x):
    try:
        return inner(x)
    except ValueError as exc:
        return str(exc)

def outer_raises(x):
    return inner(x)

def outer_in_place(a):
    b = bump(a)
    return b is a, a.copy()

def outer_not_plain(x):
    return inner(x, rng=lambda: 0)       # a lambda cannot cross: the student's own inner runs
"""


def _in_process(name, *args):
    """The oracle: the notebook's outer functions run here with the reference's inner and bump."""
    namespace = {"inner": inner, "bump": bump}
    exec(OUTER, namespace)  # noqa: S102 - the test's own source
    return namespace[name](*args)


def _answers(exercise):
    below = {
        name: frozenset({"inner", "bump"})
        for name in ("outer", "outer_catches", "outer_raises", "outer_in_place", "outer_not_plain")
    }
    answers = Answers(REFERENCE, below)
    answers.exercise = exercise
    return answers


@pytest.fixture(scope="module")
def submission(tmp_path_factory):
    path = write_notebook(tmp_path_factory.mktemp("answers") / "nb.ipynb", STUDENT_INNER, OUTER)
    answers = _answers("outer")
    with open_submission(path, limits=TEST_LIMITS, answers=answers) as sub:
        yield sub, answers


def test_the_exercises_below_answer_as_the_reference_with_the_same_draws(submission):
    """outer's result equals the oracle's exactly: both generator draws and the one after them."""
    sub, answers = submission
    answers.exercise = "outer"
    x = np.array([0.5, 1.5, 2.0])
    got = sub.outer(x, np.random.default_rng(7))
    expected = _in_process("outer", x, np.random.default_rng(7))
    np.testing.assert_array_equal(
        got, expected, err_msg="outer through the grader vs in-process with the reference inner"
    )


def test_a_refusal_of_the_reference_is_raised_in_the_student_code(submission):
    """Bad input to a stub raises the reference's ValueError where the student can catch it."""
    sub, answers = submission
    answers.exercise = "outer_catches"
    caught = sub.outer_catches(np.array([-1.0]))
    assert caught == _in_process("outer_catches", np.array([-1.0])), (
        f"outer_catches([-1]): expected the reference's message, got {caught!r}"
    )
    answers.exercise = "outer_raises"
    with pytest.raises(ValueError, match="x must be >= 0") as info:
        sub.outer_raises(np.array([-1.0]))
    assert isinstance(info.value, StudentCodeError), f"expected a student error, got {info.value!r}"


def test_in_place_changes_and_aliasing_of_the_reference_reach_the_student(submission):
    """The reference's a += 1; return a: the student's array changes and the result is it."""
    sub, answers = submission
    answers.exercise = "outer_in_place"
    a = np.arange(3.0)
    got = sub.outer_in_place(a.copy())
    expected = _in_process("outer_in_place", a.copy())
    assert got[0] is True and expected[0] is True, f"bump(a) is a: expected True, got {got[0]}"
    np.testing.assert_array_equal(got[1], expected[1], err_msg="a after bump(a)")


def test_arguments_that_cannot_cross_run_the_student_function(submission):
    """A lambda among the arguments is not plain data: the student's own inner runs (and raises)."""
    sub, answers = submission
    answers.exercise = "outer_not_plain"
    with pytest.raises(RuntimeError, match="must never run"):
        sub.outer_not_plain(np.array([1.0]))


def test_without_an_exercise_every_call_is_the_student_code(submission):
    """Outside a graded test, and after one, the notebook's own functions are back in place."""
    sub, answers = submission
    answers.exercise = None
    np.testing.assert_array_equal(sub.bump(np.ones(2)), np.zeros(2), err_msg="student's bump")
    with pytest.raises(RuntimeError, match="must never run"):
        sub.outer(np.array([1.0]), np.random.default_rng(0))


def test_a_worker_told_an_answer_never_grades_that_exercise(submission):
    """Once inner's reference answered in a worker, inner is graded in a fresh one."""
    sub, answers = submission
    answers.exercise = "outer"
    sub.outer(np.array([1.0]), np.random.default_rng(0))  # inner answered by the reference
    told = sub._worker.process.pid
    answers.exercise = "outer_catches"
    sub.outer_catches(np.array([2.0]))
    assert sub._worker.process.pid == told, "grading another exercise keeps the worker"
    answers.exercise = "inner"
    with pytest.raises(RuntimeError, match="must never run"):
        sub.inner(np.array([1.0]))
    assert sub._worker.process.pid != told, (
        "inner is graded in the worker that was given inner's reference answers: it could "
        "have kept them"
    )


def test_a_test_calling_an_exercise_below_gets_the_reference(submission):
    """A hidden test's own call of inner while it grades outer is the reference's, in the grader."""
    sub, answers = submission
    answers.exercise = "outer"
    assert sub.inner is inner, "lab.inner while grading outer must be the reference function"
    answers.exercise = "inner"
    with pytest.raises(RuntimeError, match="must never run"):
        sub.inner(np.array([1.0]))


def test_a_depcall_for_a_name_that_is_not_below_is_refused(submission):
    """A forged depcall (student code writing to the pipe) for another name is a protocol error."""
    sub, _ = submission
    handler = sub._depcalls(5, ("inner",))
    for message in [
        ("depcall", 5, "outer", (1.0,), {}, {}),  # not below: its reference would be the answer
        ("depcall", 4, "inner", (1.0,), {}, {}),  # another call's id
        ("depcall", 5, "inner", (1.0,)),  # malformed
    ]:
        with pytest.raises(StudentCodeError) as info:
            handler(message)
        assert info.value.kind == "protocol", f"{message}: expected a protocol error"
    assert handler(("depcall", 5, "inner", (1.0,), {}, {}))[0] == "answer"


def test_dependency_table_follows_helpers_and_declarations(tmp_path):
    """Below = what the reference refers to through helpers, plus USES, transitively; no cycles."""
    solution = tmp_path / "sol.py"
    solution.write_text(
        "def a(x):\n    return x\n\n"
        "def _helper(x):\n    return a(x)\n\n"
        "def b(x):\n    return _helper(x)\n\n"
        "def c(x):\n    return b(x)\n\n"
        "def d(x):\n    return x\n"
    )
    table = dependency_table(solution, ["a", "b", "c", "d"], {"d": ["c"]})
    expected = {
        "a": set(),
        "b": {"a"},
        "c": {"a", "b"},
        "d": {"a", "b", "c"},
    }
    assert {k: set(v) for k, v in table.items()} == expected, f"got {table}"
    with pytest.raises(DependencyCycle, match="below itself"):
        dependency_table(solution, ["a", "b", "c", "d"], {"a": ["c"]})


LABS = [lab for lab in discover_labs() if lab.notebook is not None and lab.hidden_tests.is_file()]


@pytest.mark.parametrize("lab", LABS, ids=[lab.name for lab in LABS])
def test_every_lab_has_an_acyclic_table_covering_what_its_tests_declare(lab):
    """Each lab's table builds (no exercise below itself) and holds its hidden tests' USES."""
    import importlib

    module = importlib.import_module(f"tests.labs.test_{lab.name}")
    declared = getattr(module, "USES", {}) or {}
    table = Answers.for_lab(lab.name, declared).below
    assert set(table) == set(lab_exercises(lab.name)), f"{lab.name}: {sorted(table)}"
    for exercise, used in declared.items():
        assert set(used) <= table[exercise], f"{lab.name}: {exercise} below {table[exercise]}"


def test_only_the_suspects_answer_as_the_reference(submission):
    """With suspects named, the other exercises below run as the student wrote them."""
    sub, answers = submission
    answers.exercise = "outer_in_place"
    answers.suspects = frozenset({"inner"})  # bump passes its own tests: the student's runs
    try:
        same, after = sub.outer_in_place(np.arange(3.0))
        assert same is False, "the student's bump returns a new array: bump(a) is not a"
        np.testing.assert_array_equal(after, np.arange(3.0), err_msg="the student's bump")
        answers.suspects = frozenset({"bump"})
        same, after = sub.outer_in_place(np.arange(3.0))
        assert same is True, "bump is a suspect: the reference's bump returns its argument"
    finally:
        answers.suspects = None
