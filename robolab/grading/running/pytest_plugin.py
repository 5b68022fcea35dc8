"""pytest plugin for the hidden lab tests.

A hidden test module ``tests/labs/test_<lab>.py`` asks for the ``lab`` fixture
and calls exercise functions on it (``lab.p_hit(...)``). By default ``lab`` is
the reference module ``solutions.<lab>``; with ``pytest --notebook PATH`` it is
a proxy to the student's notebook running in an isolated worker process.

A hidden test module may set ``GRADING_LIMITS = {"cpu_seconds": 2, ...}`` (the
fields of :class:`robolab.grading.running.proxy.Limits`) to tighten or relax the
worker's per-call limits for its lab: a lab of microsecond functions should not
let a hanging submission cost a minute per test. ``REFERENCE_CPU_SECONDS`` (the CPU
time the reference solution's worker uses while graded) sets the submission's total
CPU budget to a few times that, and its wall backstop with it
(:func:`robolab.grading.running.proxy.reference_limits`).

Every hidden test carries the ``grades`` marker naming the exercise function it
grades and its points (a positive number). A test under ``tests/labs/`` without
it, or with a malformed one, stops the session at collection.

With ``--grading-report PATH`` the plugin writes what the grader needs as JSON::

    {"notebook": str | null, "exitstatus": int,
     "tests": [{"nodeid", "name", "description", "exercise", "points",
                "outcome": "passed" | "failed" | "error" | "skipped", "message"}],
     "problems": [{"cell_index", "kind", "message"}],   # from loading the notebook
     "usage": {"cpu_seconds", "awake_seconds", "limits": [str], ...} | null,
     "collection_errors": [str]}

``usage`` is the submission's time (:meth:`SubmissionProxy.usage`) and what a limit
cut short, which the gradebook flags.

Two more markers shape the credit and the feedback (``docs/grading.md``):

- ``@pytest.mark.requires("test_a", "test_b")``: the test earns its points only
  when the named tests of the same module (every parametrization) pass too. A
  refusal test (``pytest.raises`` on bad input) requires the tests that show the
  function works on valid input, so a function that always raises earns nothing;
  an end-to-end test requires the core formula's tests, so a wrong formula cannot
  keep the end-to-end points. A gated test that passed on its own is reported as
  failed, with a message naming the tests it waits for. The named tests must grade
  the same exercise (refused at collection otherwise): a mistake costs once.
- ``@pytest.mark.uses("p_max", ...)`` (or a module-level table ``USES =
  {"beam_range_finder_model": ["p_hit", ...]}`` applying to every test of an
  exercise): the test relies on other exercises, which the student's function
  may call. ``USES`` also adds to the exercises below each one
  (:func:`robolab.grading.running.answers.dependency_table`), which answer as the
  reference while it is graded. When one of those fails its own tests, the
  failure message of this test notes it and points to that exercise's section.

While a test runs, the proxy knows the exercise it grades (its ``grades``
marker): the exercises below that one answer as the reference
(:mod:`robolab.grading.running.answers`), so each exercise's points measure its own logic.

``message`` is the failure's own message (pytest's ``reprcrash.message``, or the
student's traceback when the student's code raised), never the hidden test's
source lines.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from robolab.grading.running.credit import settle
from robolab.grading.running.failures import (
    MAX_MESSAGE_CHARS,
    describe,
    failure_message,
    report_crash_only,
    title_of,
    tracebacks_unshown,
)

# nbformat -> jsonschema imports the optional rfc3987_syntax, which builds a parser
# at import time: about 2 s of CPU in every grading process. Grading never checks
# IRI formats in notebook JSON, so make that optional import fail fast instead.
sys.modules.setdefault("rfc3987_syntax", None)  # type: ignore[arg-type]

MARKER = "grades"
#: Marker: the test pays only when the named tests of its module pass.
REQUIRES = "requires"
#: Marker: the exercises (student functions) a test relies on besides its own.
USES = "uses"

_problems_key = pytest.StashKey[list]()
_proxies_key = pytest.StashKey[list]()
_collector_key = pytest.StashKey["GradingCollector"]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("robolab")
    group.addoption(
        "--notebook",
        action="store",
        default=None,
        metavar="PATH",
        help="grade the student notebook at PATH instead of the reference solutions",
    )
    group.addoption(
        "--grading-report",
        action="store",
        default=None,
        metavar="PATH",
        help="write per-test exercise, points, outcome and failure message as JSON to PATH",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", f"{MARKER}(exercise, points): hidden test grading one exercise function"
    )
    config.addinivalue_line(
        "markers", f"{REQUIRES}(*tests): the test pays only when these tests of its module pass"
    )
    config.addinivalue_line(
        "markers", f"{USES}(*exercises): other exercises this test relies on (for the feedback)"
    )
    config.stash[_problems_key] = []
    config.stash[_proxies_key] = []
    path = config.getoption("--grading-report")
    if path:
        collector = GradingCollector(Path(path), config)
        config.stash[_collector_key] = collector
        config.pluginmanager.register(collector, "robolab-grading-collector")
        _skip_collections_at_exit(config)


def _skip_collections_at_exit(config: pytest.Config) -> None:
    """No full garbage collections when a grading run ends (pytest makes two, to report
    exceptions raised in ``__del__`` then; the report is written and the process is about to
    exit): a twentieth of a small lab's grading time. What pytest's own ``pytester`` does."""
    try:
        from _pytest.unraisableexception import gc_collect_iterations_key
    except ImportError:  # another pytest: it collects as before
        return
    config.stash[gc_collect_iterations_key] = 0


def lab_name_of(module_name: str) -> str:
    """``tests.labs.test_beam_model`` -> ``beam_model``."""
    leaf = module_name.rsplit(".", 1)[-1]
    if not leaf.startswith("test_"):
        raise ValueError(f"hidden test module {module_name!r} must be named test_<lab>")
    return leaf[len("test_") :]


@pytest.fixture(scope="module")
def lab(request: pytest.FixtureRequest):
    """The exercise functions under test: ``solutions.<lab>`` or the student's notebook."""
    name = lab_name_of(request.module.__name__)
    notebook = request.config.getoption("--notebook")
    if notebook is None:
        return importlib.import_module(f"solutions.{name}")
    from robolab.grading.running.proxy import Limits, open_submission, reference_limits

    limits = Limits(**(getattr(request.module, "GRADING_LIMITS", None) or {}))
    reference = getattr(request.module, "REFERENCE_CPU_SECONDS", None)
    if reference is not None:
        # the submission's total CPU time: a few times the reference solution's
        limits = reference_limits(limits, reference)
    from robolab.grading.running.answers import Answers

    # While a test grades an exercise, the exercises below it answer as the reference.
    answers = Answers.for_lab(name, getattr(request.module, "USES", None))
    grading = request.config.stash.setdefault(_grading_key, _Grading())
    grading.answers.append(answers)
    answers.exercise = grading.exercise
    proxy = open_submission(notebook, lab=name, limits=limits, answers=answers)
    request.addfinalizer(proxy.close)
    request.config.stash[_proxies_key].append(proxy)
    request.config.stash[_problems_key].extend(_plain(p) for p in getattr(proxy, "problems", []))
    return proxy


@dataclasses.dataclass
class _Grading:
    """The exercise the running test grades, the answers that must know it, and which
    exercises have passed every one of their tests so far."""

    exercise: str | None = None
    answers: list = dataclasses.field(default_factory=list)
    tests: dict = dataclasses.field(default_factory=dict)  # (module, exercise) -> tests
    passed: dict = dataclasses.field(default_factory=dict)  # (module, exercise) -> passed

    def clean(self, module: str, exercise: str) -> bool:
        """Every test of ``exercise`` in ``module`` has run and passed."""
        key = (module, exercise)
        return self.passed.get(key, 0) >= self.tests.get(key, 0)


_grading_key = pytest.StashKey[_Grading]()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    # Before the fixtures: a module fixture calling the notebook already grades this exercise.
    grading = item.config.stash.setdefault(_grading_key, _Grading())
    try:
        grade = grade_of(item)
    except ValueError:  # refused at collection already
        grade = None
    grading.exercise = grade.exercise if grade is not None else None
    module = item.nodeid.split("::")[0]
    for answers in grading.answers:
        answers.exercise = grading.exercise
        # Answered by the reference only where needed: an exercise below this one that
        # passes all its own tests (they run first) runs as the student wrote it, so a
        # correct notebook is graded without a single call-back.
        answers.suspects = frozenset(
            below
            for below in answers.below.get(grading.exercise, ())
            if not grading.clean(module, below)
        )


@contextlib.contextmanager
def _refusing(error: type[BaseException], bad_input: str) -> Iterator[None]:
    if not isinstance(bad_input, str) or not bad_input.strip():
        raise TypeError("refuses(error, bad_input): bad_input names the input, e.g. 'sigma = -1'")
    try:
        yield
    except error:
        return
    pytest.fail(
        f"expected {error.__name__} for {bad_input}, but the function returned normally: the "
        "docstring asks to refuse such input with a clear error, not to compute on it",
        pytrace=False,
    )


@pytest.fixture
def refuses():
    """A refusal check that names its bad input in the feedback::

        with refuses(ValueError, "sigma_hit = -0.1 (a standard deviation must be > 0)"):
            lab.p_hit(1.0, 1.0, 5.0, -0.1)

    Passes when the block raises ``error`` (a subclass included); fails, naming
    ``bad_input``, when it returns normally. Any other exception propagates, as
    with ``pytest.raises`` (a stub's NotImplementedError stays "not implemented").
    """
    return _refusing


# --- the grades marker ------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Grade:
    """What one hidden test is worth."""

    exercise: str
    points: float


def grade_of(item: pytest.Item) -> Grade | None:
    """The item's ``grades`` marker as a Grade, None without one.

    Raises
    ------
    ValueError
        When the marker is malformed: missing exercise or points, points <= 0,
        or more than one ``grades`` marker.
    """
    marks = list(item.iter_markers(MARKER))
    if not marks:
        return None
    if len(marks) > 1:
        raise ValueError("has more than one grades marker; a test grades exactly one exercise")
    mark = marks[0]
    args = list(mark.args)
    exercise = mark.kwargs.get("exercise", args.pop(0) if args else None)
    points = mark.kwargs.get("points", args.pop(0) if args else None)
    extra = set(mark.kwargs) - {"exercise", "points"}
    if args or extra:
        raise ValueError(
            f"grades takes (exercise, points=N) only, got extra {args or sorted(extra)}"
        )
    if not isinstance(exercise, str) or not exercise.isidentifier():
        raise ValueError(f"grades needs the exercise's function name first, got {exercise!r}")
    if isinstance(points, bool) or not isinstance(points, (int, float)) or not points > 0:
        raise ValueError(f"grades needs points=N with N > 0, got {points!r}")
    return Grade(exercise, float(points))


def _base_name(item: pytest.Item) -> str:
    """The test function's name without its parametrization."""
    return getattr(item, "originalname", None) or item.name.split("[")[0]


def required_of(item: pytest.Item) -> list[str]:
    """Names of the tests (of the same module) that ``item`` waits for."""
    names: list[str] = []
    for mark in item.iter_markers(REQUIRES):
        names += [n for n in mark.args if n not in names]
    return names


def uses_of(item: pytest.Item) -> list[str]:
    """The exercises ``item`` relies on besides its own: its ``uses`` marker and ``USES``."""
    names: list[str] = []
    for mark in item.iter_markers(USES):
        names += [n for n in mark.args if n not in names]
    grade = grade_of(item)
    table = getattr(getattr(item, "module", None), "USES", None) or {}
    if grade is not None:
        names += [n for n in table.get(grade.exercise, []) if n not in names]
    return [n for n in names if grade is None or n != grade.exercise]


def _check_requires(
    item: pytest.Item, exercises: dict[tuple[str, str], set[str]], exercise: str | None
) -> str | None:
    wanted = required_of(item)
    module = item.nodeid.split("::")[0]
    if any(not isinstance(n, str) for n in wanted):
        return f"{REQUIRES} takes test function names, got {wanted!r}"
    unknown = [n for n in wanted if (module, n) not in exercises]
    if unknown:
        return f"{REQUIRES} names tests that {module} does not have: {unknown}"
    if _base_name(item) in wanted:
        return f"{REQUIRES} names the test itself"
    # A mistake costs once: a test pays for its own exercise, whatever the others do.
    foreign = [n for n in wanted if exercises[(module, n)] - {exercise}]
    if foreign:
        return (
            f"{REQUIRES} names tests of other exercises than {exercise}: {foreign} (a test's "
            "points may wait only for its own exercise's tests; the exercises it builds on "
            "answer as the reference while it is graded)"
        )
    return None


# A gated test whose required tests already failed cannot pay: it is not run (an end-to-end
# run of a broken filter can take a minute) and fails at once, naming what it waits for.
_failed_key = pytest.StashKey[set]()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    report = yield
    if report.when == "call" and report.passed:
        grading = item.config.stash.setdefault(_grading_key, _Grading())
        grade = grade_of(item)
        if grade is not None:
            key = (item.nodeid.split("::")[0], grade.exercise)
            grading.passed[key] = grading.passed.get(key, 0) + 1
    # A stub's NotImplementedError is cheap to meet again, and its feedback ("not implemented
    # yet") is clearer than "not run": only other failures make the gated tests skip.
    stub = call.excinfo is not None and call.excinfo.errisinstance(NotImplementedError)
    if report.failed and not stub:
        item.config.stash.setdefault(_failed_key, set()).add(
            (item.nodeid.split("::")[0], _base_name(item))
        )
    return report


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    failed = pyfuncitem.config.stash.get(_failed_key, set())
    module = pyfuncitem.nodeid.split("::")[0]
    waiting = [n for n in required_of(pyfuncitem) if (module, n) in failed]
    if waiting:
        titles = {
            _base_name(it): title_of(getattr(getattr(it, "obj", None), "__doc__", None))
            or _base_name(it)
            for it in pyfuncitem.session.items
            if it.nodeid.split("::")[0] == module and _base_name(it) in waiting
        }
        pytest.fail(
            "Not run: this check counts only when "
            + ", ".join(f'"{titles.get(n, n)}"' for n in waiting)
            + " also pass, and they fail; fix those first.",
            pytrace=False,
        )
    return None


def _is_hidden_test(item: pytest.Item) -> bool:
    folder = Path(str(item.path)).parent
    return folder.name == "labs" and folder.parent.name == "tests"


def pytest_collection_modifyitems(
    session: pytest.Session, config: pytest.Config, items: list[pytest.Item]
) -> None:
    problems = []
    exercises: dict[tuple[str, str], set[str]] = {}  # (module, test) -> exercises it grades
    grading = config.stash.setdefault(_grading_key, _Grading())
    for item in items:
        try:
            grade = grade_of(item)
        except ValueError:
            grade = None
        if grade is not None:
            key = (item.nodeid.split("::")[0], grade.exercise)
            grading.tests[key] = grading.tests.get(key, 0) + 1
        exercises.setdefault((item.nodeid.split("::")[0], _base_name(item)), set()).add(
            grade.exercise if grade is not None else None
        )
    for item in items:
        try:
            grade = grade_of(item)
        except ValueError as exc:
            problems.append(f"{item.nodeid}: {exc}")
            continue
        exercise = grade.exercise if grade is not None else None
        if (bad := _check_requires(item, exercises, exercise)) is not None:
            problems.append(f"{item.nodeid}: {bad}")
        if grade is None and _is_hidden_test(item):
            problems.append(
                f"{item.nodeid}: hidden tests must be marked "
                f'@pytest.mark.{MARKER}("<exercise>", points=N)'
            )
    if problems:
        raise pytest.UsageError("malformed hidden tests:\n  " + "\n  ".join(problems))


# --- the results collector --------------------------------------------------------------------


def _usage(proxies: list) -> dict | None:
    """The submission's time and the limits that cut it short, over its proxies (one a lab)."""
    usages = [p.usage() for p in proxies if callable(getattr(p, "usage", None))]
    if not usages:
        return None
    total = {key: sum(u[key] for u in usages) for key in ("cpu_seconds", "awake_seconds")}
    total["longest_call_cpu_seconds"] = max(u["longest_call_cpu_seconds"] for u in usages)
    total["limits"] = [line for u in usages for line in u["limits"]]
    return total


def _plain(obj: Any) -> dict:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {
            k: v if isinstance(v, (int, float, str, type(None))) else str(v)
            for k, v in dataclasses.asdict(obj).items()
        }
    return {f: str(getattr(obj, f, "")) for f in ("cell_index", "kind", "message")}


class GradingCollector:
    """Collects one record per test and keeps the grading report up to date on disk.

    The report is rewritten after collection (every test "not run") and after
    each test, so a run stopped by the grader's timeout still reports what passed.
    """

    def __init__(self, path: Path, config: pytest.Config) -> None:
        self.path = path
        self.config = config
        self.records: dict[str, dict] = {}
        self.collection_errors: list[str] = []

    def _record(self, item: pytest.Item) -> dict:
        grade = grade_of(item)
        return self.records.setdefault(
            item.nodeid,
            {
                "nodeid": item.nodeid,
                "name": item.name,
                "description": describe(item),
                "exercise": grade.exercise if grade else None,
                "points": grade.points if grade else 0.0,
                "outcome": "not run",
                "message": "",
                "module": item.nodeid.split("::")[0],
                "test": _base_name(item),
                "requires": required_of(item),
                "uses": uses_of(item),
            },
        )

    def pytest_collectreport(self, report: pytest.CollectReport) -> None:
        if report.failed:
            self.collection_errors.append(
                f"{report.nodeid}: {str(report.longrepr)[-MAX_MESSAGE_CHARS:]}"
            )

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        quiet = tracebacks_unshown(self.config)
        for item in session.items:
            self._record(item)
            if quiet:
                report_crash_only(item)
        self.write(exitstatus=None)

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_makereport(self, item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
        report = yield
        record = self._record(item)
        if report.when == "teardown":
            # Closing the worker can fail after a fair pass; that must not cost the student.
            return report
        if report.failed:
            crash = getattr(getattr(report, "longrepr", None), "reprcrash", None)
            exc = call.excinfo.value if call.excinfo is not None else None
            record["outcome"] = "failed" if report.when == "call" else "error"
            record["message"] = failure_message(exc, getattr(crash, "message", None))
        elif report.skipped:
            record["outcome"] = "skipped"
            longrepr = report.longrepr
            record["message"] = str(longrepr[2]) if isinstance(longrepr, tuple) else "skipped"
        elif report.when == "call" and record["outcome"] == "not run":
            record["outcome"] = "passed"
        return report

    def pytest_runtest_logfinish(self, nodeid: str, location: tuple) -> None:
        self.write(exitstatus=None)

    def pytest_sessionfinish(self, session: pytest.Session, exitstatus: int) -> None:
        self.write(exitstatus=int(exitstatus))

    def write(self, exitstatus: int | None) -> None:
        """Write the report atomically (a reader never sees half a file)."""
        data = {
            "notebook": self.config.getoption("--notebook"),
            "exitstatus": exitstatus,
            "tests": settle(list(self.records.values())),
            "problems": self.config.stash[_problems_key],
            "usage": _usage(self.config.stash[_proxies_key]),
            "collection_errors": self.collection_errors,
        }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(self.path.name + ".part")
        # No indent: json's C encoder (indented output is the pure-Python one, written
        # after every test of every submission).
        tmp.write_text(json.dumps(data))
        tmp.replace(self.path)
