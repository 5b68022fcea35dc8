"""pytest plugin for the hidden lab tests.

A hidden test module ``tests/labs/test_<lab>.py`` asks for the ``lab`` fixture
and calls exercise functions on it (``lab.p_hit(...)``). By default ``lab`` is
the reference module ``solutions.<lab>``; with ``pytest --notebook PATH`` it is
a proxy to the student's notebook running in an isolated worker process.

A hidden test module may set ``GRADING_LIMITS = {"cpu_seconds": 2, ...}`` (the
fields of :class:`robolab.grading.proxy.Limits`) to tighten or relax the
worker's per-call limits for its lab: a lab of microsecond functions should not
let a hanging submission cost a minute per test.

Every hidden test carries the ``grades`` marker naming the exercise function it
grades and its points (a positive number). A test under ``tests/labs/`` without
it, or with a malformed one, stops the session at collection.

With ``--grading-report PATH`` the plugin writes what the grader needs as JSON::

    {"notebook": str | null, "exitstatus": int,
     "tests": [{"nodeid", "name", "description", "exercise", "points",
                "outcome": "passed" | "failed" | "error" | "skipped", "message"}],
     "problems": [{"cell_index", "kind", "message"}],   # from loading the notebook
     "collection_errors": [str]}

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
    from robolab.grading.proxy import Limits, open_submission  # the isolated worker

    overrides = getattr(request.module, "GRADING_LIMITS", None)
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


def _is_hidden_test(item: pytest.Item) -> bool:
    folder = Path(str(item.path)).parent
    return folder.name == "labs" and folder.parent.name == "tests"


def pytest_collection_modifyitems(
    session: pytest.Session, config: pytest.Config, items: list[pytest.Item]
) -> None:
    problems = []
    for item in items:
        try:
            grade = grade_of(item)
        except ValueError as exc:
            problems.append(f"{item.nodeid}: {exc}")
            continue
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
            "tests": list(self.records.values()),
            "problems": self.config.stash[_problems_key],
            "collection_errors": self.collection_errors,
        }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(self.path.name + ".part")
        tmp.write_text(json.dumps(data, indent=1))
        tmp.replace(self.path)
