"""pytest plugin for the hidden lab tests.

A hidden test module ``tests/labs/test_<lab>.py`` asks for the ``lab`` fixture
and calls exercise functions on it (``lab.p_hit(...)``). By default ``lab`` is
the reference module ``solutions.<lab>``; with ``pytest --notebook PATH`` it is
a proxy to the student's notebook running in an isolated worker process.

A hidden test module may set ``GRADING_LIMITS = {"cpu_seconds": 2, ...}`` (the
fields of :class:`robolab.grading.running.proxy.Limits`) to tighten or relax the
worker's per-call limits for its lab: a lab of microsecond functions should not
let a hanging submission cost a minute per test. ``REFERENCE_SECONDS`` (the
reference solution's grading time) sets the submission's total time budget to a
few times that (:func:`robolab.grading.running.proxy.reference_budget`).

Every hidden test carries the ``grades`` marker naming the exercise function it
grades and its points (a positive number). A test under ``tests/labs/`` without
it, or with a malformed one, stops the session at collection.

With ``--grading-report PATH`` the plugin writes what the grader needs as JSON::

    {"notebook": str | null, "exitstatus": int,
     "tests": [{"nodeid", "name", "description", "exercise", "points",
                "outcome": "passed" | "failed" | "error" | "skipped", "message"}],
     "problems": [{"cell_index", "kind", "message"}],   # from loading the notebook
     "collection_errors": [str]}

Two more markers shape the credit and the feedback (``docs/grading.md``):

- ``@pytest.mark.requires("test_a", "test_b")``: the test earns its points only
  when the named tests of the same module (every parametrization) pass too. A
  refusal test (``pytest.raises`` on bad input) requires the tests that show the
  function works on valid input, so a function that always raises earns nothing;
  an end-to-end test requires the core formula's tests, so a wrong formula cannot
  keep the end-to-end points. A gated test that passed on its own is reported as
  failed, with a message naming the tests it waits for.
- ``@pytest.mark.uses("p_max", ...)`` (or a module-level table ``USES =
  {"beam_range_finder_model": ["p_hit", ...]}`` applying to every test of an
  exercise): the test relies on other exercises, which the student's function
  may call. When one of those fails its own tests, the failure message of this
  test says so and points to that exercise's section of the feedback.

``message`` is the failure's own message (pytest's ``reprcrash.message``, or the
student's traceback when the student's code raised), never the hidden test's
source lines.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

# nbformat -> jsonschema imports the optional rfc3987_syntax, which builds a parser
# at import time: about 2 s of CPU in every grading process. Grading never checks
# IRI formats in notebook JSON, so make that optional import fail fast instead.
sys.modules.setdefault("rfc3987_syntax", None)  # type: ignore[arg-type]

MARKER = "grades"
#: Marker: the test pays only when the named tests of its module pass.
REQUIRES = "requires"
#: Marker: the exercises (student functions) a test relies on besides its own.
USES = "uses"
#: Longest failure message kept in a report; longer ones are cut in the middle.
MAX_MESSAGE_CHARS = 2000

_problems_key = pytest.StashKey[list]()
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
    path = config.getoption("--grading-report")
    if path:
        collector = GradingCollector(Path(path), config)
        config.stash[_collector_key] = collector
        config.pluginmanager.register(collector, "robolab-grading-collector")


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
    from robolab.grading.running.proxy import Limits, open_submission, reference_budget

    overrides = dict(getattr(request.module, "GRADING_LIMITS", None) or {})
    reference = getattr(request.module, "REFERENCE_SECONDS", None)
    if reference is not None and "total_wall_seconds" not in overrides:
        # the submission's total call time: a few times the reference solution's
        overrides["total_wall_seconds"] = reference_budget(Limits(**overrides), reference)
    proxy = open_submission(notebook, lab=name, limits=Limits(**overrides) if overrides else None)
    request.addfinalizer(proxy.close)
    request.config.stash[_problems_key].extend(_plain(p) for p in getattr(proxy, "problems", []))
    return proxy


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


def _check_requires(item: pytest.Item, names_by_module: dict[str, set[str]]) -> str | None:
    wanted = required_of(item)
    module = item.nodeid.split("::")[0]
    if any(not isinstance(n, str) for n in wanted):
        return f"{REQUIRES} takes test function names, got {wanted!r}"
    unknown = [n for n in wanted if n not in names_by_module.get(module, set())]
    if unknown:
        return f"{REQUIRES} names tests that {module} does not have: {unknown}"
    if _base_name(item) in wanted:
        return f"{REQUIRES} names the test itself"
    return None


# A gated test whose required tests already failed cannot pay: it is not run (an end-to-end
# run of a broken filter can take a minute) and fails at once, naming what it waits for.
_failed_key = pytest.StashKey[set]()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    report = yield
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
            _base_name(it): describe(it).split(" [")[0]
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
    names_by_module: dict[str, set[str]] = {}
    for item in items:
        names_by_module.setdefault(item.nodeid.split("::")[0], set()).add(_base_name(item))
    for item in items:
        try:
            grade = grade_of(item)
        except ValueError as exc:
            problems.append(f"{item.nodeid}: {exc}")
            continue
        if (bad := _check_requires(item, names_by_module)) is not None:
            problems.append(f"{item.nodeid}: {bad}")
        if grade is None and _is_hidden_test(item):
            problems.append(
                f"{item.nodeid}: hidden tests must be marked "
                f'@pytest.mark.{MARKER}("<exercise>", points=N)'
            )
    if problems:
        raise pytest.UsageError("malformed hidden tests:\n  " + "\n  ".join(problems))


# --- the results collector --------------------------------------------------------------------


def describe(item: pytest.Item) -> str:
    """A test's name in words: its docstring's first line, else its name without ``test_``."""
    doc = (getattr(getattr(item, "obj", None), "__doc__", None) or "").strip()
    base = (
        doc.splitlines()[0].strip()
        if doc
        else item.name.split("[")[0].removeprefix("test_").replace("_", " ")
    )
    param = item.name[len(item.name.split("[")[0]) :]
    return base + (f" {param}" if param else "")


_REWRITE_TAIL = re.compile(r"\n(assert |\s*\+\s+where ).*", re.DOTALL)
_DID_NOT_RAISE = re.compile(r"DID NOT RAISE (?:<class '(?:[\w.]*\.)?(\w+)'>|\(?([\w., ]+)\)?)")


def failure_message(exc: BaseException | None, crash_message: str | None) -> str:
    """The failure in words, without hidden test source.

    The student's traceback when the student's code raised (the proxy attaches
    ``student_traceback``); otherwise the exception's message as pytest reports
    it, with the assertion-rewrite explanation dropped when the assertion has a
    message of its own.
    """
    student_tb = getattr(exc, "student_traceback", None)
    message = getattr(exc, "message", None)
    if student_tb:
        kind = getattr(exc, "kind", None) or type(exc).__name__
        text = f"{kind}: {message}\n{student_tb}" if message else f"{kind}\n{student_tb}"
    elif student_tb is not None and isinstance(message, str):
        text = message  # the proxy's own words: a crash, a timeout, a result that is not plain data
    else:
        text = crash_message or (f"{type(exc).__name__}: {exc}" if exc is not None else "")
        head = _REWRITE_TAIL.sub("", text)
        if head.strip() and head.strip() not in ("AssertionError", "AssertionError:"):
            text = head
    text = text.strip()
    if (missed := _DID_NOT_RAISE.search(text)) is not None:
        kind = missed.group(1) or missed.group(2) or "an error"
        text = (
            f"expected {kind} for the bad input this check names, but the function returned "
            "normally: the text asks to refuse such input with a clear error, not to compute "
            "on it"
        )
    if len(text) > MAX_MESSAGE_CHARS:
        half = MAX_MESSAGE_CHARS // 2
        cut = len(text) - MAX_MESSAGE_CHARS
        text = f"{text[:half]}\n... ({cut} characters cut) ...\n{text[-half:]}"
    return text


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
        for item in session.items:
            self._record(item)
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
            "collection_errors": self.collection_errors,
        }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(self.path.name + ".part")
        # No indent: json's C encoder (indented output is the pure-Python one, written
        # after every test of every submission).
        tmp.write_text(json.dumps(data))
        tmp.replace(self.path)


# --- credit that follows the exercise's parts, and hints across exercises ---------------------


def _label(record: dict) -> str:
    return f"\"{record['description']}\""


def settle(records: list[dict]) -> list[dict]:
    """The records as the student is graded: ``requires`` gates applied, ``uses`` hints added.

    Pure: returns new dicts, the collector's own records stay as the tests ran
    (so a rewrite after a later test starts again from the raw outcomes).

    - A passed test whose required tests did not all pass becomes "failed", with
      a message naming them (repeated until nothing changes: gates can chain).
    - A failed test that uses an exercise which fails some of its own tests gets
      a closing sentence pointing to that exercise's section.
    """
    out = [dict(r) for r in records]
    by_test: dict[tuple[str, str], list[dict]] = {}
    for r in out:
        by_test.setdefault((r.get("module", ""), r.get("test", "")), []).append(r)
    changed = True
    while changed:
        changed = False
        for r in out:
            if r["outcome"] != "passed" or not r.get("requires"):
                continue
            waiting = [
                other
                for name in r["requires"]
                for other in by_test.get((r.get("module", ""), name), [])
                if other["outcome"] != "passed"
            ]
            if waiting:
                r["outcome"] = "failed"
                r["gated"] = True
                r["message"] = (
                    f"This check passed on its own, but it counts only when `{r['exercise']}` "
                    f"also passes {', '.join(_label(w) for w in waiting[:3])}"
                    f"{' and more' if len(waiting) > 3 else ''}: refusing bad input or "
                    "finishing the whole run earns points only for a function that computes "
                    "the right values."
                )
                changed = True
    failing: dict[str, int] = {}
    for r in out:
        if r["outcome"] in ("failed", "error") and not r.get("gated"):
            failing[r["exercise"]] = failing.get(r["exercise"], 0) + 1
    for r in out:
        if r["outcome"] not in ("failed", "error"):
            continue
        culprits = [u for u in r.get("uses", []) if u in failing and u != r["exercise"]]
        if culprits:
            names = ", ".join(f"`{u}`" for u in culprits)
            r["message"] = (r.get("message") or "").rstrip() + (
                f"\n\nThis may be because {names} "
                f"{'is' if len(culprits) == 1 else 'are'} wrong: "
                f"{'it fails' if len(culprits) == 1 else 'they fail'} "
                f"{'its' if len(culprits) == 1 else 'their'} own checks, which "
                f"{r['exercise']} relies on; see the section on {names} and fix "
                f"{'it' if len(culprits) == 1 else 'them'} first."
            )
    return out
