"""The class report: counts against a hand count, self-containment, and HTML injection."""

from __future__ import annotations

import base64
import io
from datetime import datetime, timezone
from html.parser import HTMLParser
from pathlib import Path

import pytest
from PIL import Image

from robolab.grading.course.class_report import (
    failed_checks,
    render_class_report,
    write_class_report,
)
from robolab.grading.course.late import Lateness
from robolab.grading.course.report import Context, gradebook_rows
from robolab.grading.running.runner import SubmissionResult, TestOutcome

EVIL = '<script>alert("x")</script><img src=x onerror=alert(1)>&amp;"\''


def _test(exercise, n, points, passed, description=None):
    return TestOutcome(
        f"tests/labs/test_bayes.py::test_{exercise}_{n}",
        description or f"{exercise}: check number {n}",
        exercise,
        points,
        "passed" if passed else "failed",
        "" if passed else "AssertionError: expected 0.75, got 0.5",
    )


def _result(name, passes, *, lab="bayes", flags=(), errors=(), isolation=""):
    """``passes``: for checks (a,0) (a,1) (b,0), whether each passed."""
    tests = [
        _test("alpha", 0, 10, passes[0]),
        _test("alpha", 1, 20, passes[1]),
        _test("beta", 0, 70, passes[2]),
    ]
    return SubmissionResult(
        Path(f"{name}.ipynb"),
        name,
        lab,
        tests,
        flags=list(flags),
        errors=list(errors),
        isolation=isolation,
    )


@pytest.fixture
def batch():
    results = [
        _result("ann", (True, True, True)),
        _result("bob", (True, False, False)),
        _result("cyd", (False, False, True), flags=["limit: memory (cut short)"]),
        _result("dee", (True, False, True), errors=["SyntaxError: cell 3\nmore"]),
    ]
    late = {"bob": Lateness(datetime(2026, 3, 3, tzinfo=timezone.utc), 2, 20.0)}
    rows = gradebook_rows(results, Context(lateness=late))
    return results, rows


class _Tags(HTMLParser):
    def __init__(self):
        super().__init__()
        self.tags, self.images, self.text = [], [], []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        if tag == "img":
            self.images.append(dict(attrs)["src"])
        assert not any(k.startswith("on") for k, _ in attrs), (tag, attrs)

    def handle_data(self, data):
        self.text.append(data)


def test_failed_checks_are_counted_per_check_most_failed_first(batch):
    results, _ = batch
    checks = failed_checks(results)
    assert [(c["exercise"], c["title"], c["failed"], c["graded"]) for c in checks] == [
        ("alpha", "check number 1", 3, 4),
        ("beta", "check number 0", 1, 4),
        ("alpha", "check number 0", 1, 4),
    ]


def test_report_shows_distributions_checks_and_flags(batch):
    results, rows = batch
    page = render_class_report(results, rows)
    parsed = _Tags()
    parsed.feed(page)
    text = " ".join(parsed.text)
    assert "4 submission(s)" in text
    assert "check number 1" in text and "3 of 4" in text
    # self-contained: every image inline, a real PNG; no script, nothing loaded
    assert parsed.images and all(s.startswith("data:image/png;base64,") for s in parsed.images)
    for src in parsed.images:
        png = Image.open(io.BytesIO(base64.b64decode(src.split(",", 1)[1])))
        assert png.format == "PNG" and png.size[0] > 300
    assert not {"script", "link", "iframe", "object"} & set(parsed.tags)
    assert "http" not in page.replace("http-equiv", "")
    # flagged: the late one, the one cut short, the one with an error; not the clean one
    flagged = page.split("Submissions flagged")[1]
    assert "(3)" in flagged.split("</h2>")[0]
    assert "late: 2 day(s), -20%" in flagged and "limit: memory" in flagged
    assert "SyntaxError: cell 3" in flagged and "more" not in flagged
    assert "<code>ann</code>" not in flagged
    # the final points after the late penalty are what the distribution shows
    assert {r["submission"]: r["final"] for r in rows}["bob"] == pytest.approx(8.0)


@pytest.mark.parametrize("where", ["name", "lab", "flag", "error", "title", "isolation"])
def test_student_derived_text_cannot_inject_html(where):
    evil = EVIL + where
    kwargs = (
        {"flags": [evil]} if where == "flag" else {"errors": [evil]} if where == "error" else {}
    )
    if where == "isolation":
        kwargs = {"isolation": evil}
    if where == "name":  # a name is shown where the submission is flagged
        kwargs = {"flags": ["lab missing"]}
    r = _result(
        evil if where == "name" else "ann",
        (False, True, True),
        lab=evil if where == "lab" else "bayes",
        **kwargs,
    )
    if where == "title":
        r.tests[0] = _test("alpha", 0, 10, False, description=f"alpha: {evil}")
    page = render_class_report([r], gradebook_rows([r]))
    parsed = _Tags()
    parsed.feed(page)
    assert "script" not in parsed.tags
    assert all(s.startswith("data:image/png;base64,") for s in parsed.images)
    assert "<script>" not in page and "<img src=x" not in page
    assert evil in "".join(parsed.text)  # shown, as text


def test_written_beside_the_gradebook(batch, tmp_path):
    results, rows = batch
    path = write_class_report(results, rows, tmp_path)
    assert path == tmp_path / "report.html" and path.read_text().startswith("<!DOCTYPE html>")


def test_mismatched_rows_are_refused(batch):
    results, rows = batch
    with pytest.raises(ValueError, match="4 results but 3 rows"):
        render_class_report(results, rows[:3])
