"""The batch says once what protects the answers, loudly when something does not."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
from pathlib import Path

import pytest

import robolab
from robolab.grading.course.report import write_gradebook
from robolab.grading.exports import gradescope
from robolab.grading.isolation import protection, sandbox
from robolab.grading.isolation.protection import Protection, UnprotectedAnswers
from robolab.grading.isolation.sandbox import SandboxReport
from robolab.grading.running.runner import grade_all

REPOSITORY = Path(robolab.__file__).resolve().parent.parent
ISOLATED = sandbox.landlock_abi() > 0


@pytest.fixture
def unisolated(monkeypatch):
    """Workers with no sandbox at all: what a grader without Landlock or root gets."""
    original = sandbox.plan_sandbox

    def plan(*args, **kwargs):
        return dataclasses.replace(
            original(*args, **kwargs),
            view_root=None,
            drop_privileges=False,
            landlock=False,
            seccomp=False,
            user_namespace=False,
        )

    monkeypatch.setattr(sandbox, "plan_sandbox", plan)
    protection.describe_protection.cache_clear()
    yield
    protection.describe_protection.cache_clear()


@pytest.mark.skipif(not ISOLATED, reason="needs Landlock")
def test_this_machine_protects_everything_and_says_how():
    found = protection.describe_protection()
    assert found.answers_protected and found.network_protected and found.processes_protected
    assert found.readable == [] and found.reached == [] and found.column == ""
    line = found.line()
    assert line.startswith("isolation: answers unreadable") and "Landlock ABI" in line
    assert "READABLE" not in line and "OPEN" not in line
    assert protection.answers_protected()
    assert protection.describe_protection() is found  # probed once per process


@pytest.mark.filterwarnings("ignore::robolab.grading.running.proxy.IsolationWarning")
def test_an_unisolated_worker_is_caught_reading_the_answers(unisolated):
    found = protection.probe_protection()
    assert not found.answers_protected
    assert any("solutions" in p for p in found.readable)  # it really read a reference solution
    assert any("test_" in p for p in found.readable)
    assert not found.network_protected and "tcp" in found.reached
    assert found.column.startswith("UNPROTECTED: ")
    out = io.StringIO()
    found.announce(out)
    text = out.getvalue()
    assert "answers READABLE" in text and text.count("WARNING:") == len(found.problems) >= 2


@pytest.mark.filterwarnings("ignore::robolab.grading.running.proxy.IsolationWarning")
def test_gradescope_refuses_to_grade_where_answers_are_readable(unisolated, tmp_path):
    with pytest.raises(UnprotectedAnswers, match="refuses to grade"):
        protection.require_answers_protected()
    results = tmp_path / "results.json"
    with pytest.raises(UnprotectedAnswers):
        gradescope.run("demo", tmp_path, results, root=REPOSITORY)
    # Nothing was graded: Gradescope shows the student why, with no test results.
    data = json.loads(results.read_text())
    assert data["tests"] == [] and data["score"] == 0 and "not set up safely" in data["output"]


def test_a_probe_that_cannot_start_is_a_problem():
    found = Protection(None, failure="WorkerStartError: no python")
    assert not found.answers_protected and found.problems
    assert "could not be probed" in found.column and "UNKNOWN" in found.line()


def test_a_batch_announces_once_and_marks_the_gradebook(monkeypatch, capsys, tmp_path):
    weak = Protection(SandboxReport(uid=0), readable=[str(REPOSITORY / "solutions" / "demo.py")])
    calls = []
    monkeypatch.setattr(protection, "batch_protection", lambda: calls.append(1) or weak)
    notebooks = [
        REPOSITORY / "examples" / "submissions" / "demo" / n
        for n in ("correct.ipynb", "wrong.ipynb")
    ]
    results = grade_all(notebooks, lab="demo", progress=False)
    assert len(calls) == 1
    err = capsys.readouterr().err
    assert err.count("isolation: answers READABLE") == 1 and "WARNING: robolab grading" in err
    assert all(r.isolation.startswith("UNPROTECTED") for r in results)
    csv_path, _ = write_gradebook(results, tmp_path)
    rows = list(csv.DictReader(csv_path.open()))
    assert all(row["isolation"].startswith("UNPROTECTED") for row in rows)


def test_a_fully_protected_batch_has_no_isolation_column(tmp_path):
    from robolab.grading.running.runner import SubmissionResult

    csv_path, _ = write_gradebook([SubmissionResult(Path("a.ipynb"), "a", "demo")], tmp_path)
    assert "isolation" not in csv_path.read_text().splitlines()[0]
