"""Gradebook, feedback and summary table from hand-made results."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from robolab.grading.course.report import (
    render_feedback,
    summary_table,
    write_feedback,
    write_gradebook,
)
from robolab.grading.running.runner import SubmissionResult, TestOutcome


def outcome(
    exercise: str, points: float, passed: bool, message: str = "", description: str = ""
) -> TestOutcome:
    return TestOutcome(
        nodeid=f"tests/labs/test_demo.py::test_{exercise}_{points}",
        exercise=exercise,
        description=description or f"{exercise}: check worth {points}",
        points=points,
        outcome="passed" if passed else "failed",
        message=message,
    )


def partial_result() -> SubmissionResult:
    return SubmissionResult(
        path=Path("subs/alice.ipynb"),
        name="alice",
        lab="demo",
        seconds=1.234,
        tests=[
            outcome("normalize", 30, True),
            outcome("normalize", 10, True),
            outcome("wrap", 20, True),
            outcome(
                "wrap",
                10,
                False,
                "AssertionError: wrap(3.14159): expected -pi, got 3.14159",
                "wrap: both pi and -pi wrap to -pi",
            ),
            outcome("mean_pose", 25, False, "NotImplementedError: \nTraceback: cell 9"),
            outcome("mean_pose", 5, False, "NotImplementedError: \nTraceback: cell 9"),
        ],
        problems=[{"cell_index": 4, "kind": "syntax", "message": "invalid syntax (line 2)"}],
    )


def other_lab_result() -> SubmissionResult:
    return SubmissionResult(
        path=Path("subs/bob.ipynb"),
        name="bob",
        lab="bayes",
        tests=[outcome("bayes_posterior", 100, True)],
    )


def broken_result() -> SubmissionResult:
    return SubmissionResult(
        path=Path("subs/carol.ipynb"),
        name="carol",
        lab=None,
        errors=["the notebook does not say which lab it is"],
    )


def test_scores_add_up():
    r = partial_result()
    assert r.exercise_scores() == {"normalize": (40, 40), "wrap": (20, 30), "mean_pose": (0, 30)}
    assert (r.total, r.max_points) == (60, 100)


def test_feedback_says_what_failed_in_words():
    text = render_feedback(partial_result())
    assert "**60 / 100**" in text
    assert (
        "## `normalize`: 40 / 40 points" in text
        and "Every hidden check of this function passed." in text
    )
    assert "- **both pi and -pi wrap to -pi** (10 points) failed:" in text
    assert "expected -pi, got 3.14159" in text
    # a stub is named once, not as a list of failing checks
    assert "Not implemented yet: `mean_pose` still raises NotImplementedError." in text
    assert "cell 9" not in text
    # cell_index is 0-based; a student counts cells from 1
    assert "- `cell 5` (`syntax`):" in text and "invalid syntax (line 2)" in text
    assert "nodeid" not in text and "test_demo.py" not in text


def test_feedback_for_an_ungraded_submission_explains_why():
    text = render_feedback(broken_result())
    assert "## Grading problems" in text and "does not say which lab" in text
    assert "Score" not in text


def test_gradebook_has_a_row_per_submission(tmp_path):
    results = [partial_result(), other_lab_result(), broken_result()]
    csv_path, json_path = write_gradebook(results, tmp_path)
    rows = list(csv.DictReader(csv_path.open()))
    assert [r["submission"] for r in rows] == ["alice", "bob", "carol"]
    header = csv_path.read_text().splitlines()[0]
    assert header == (
        "submission,path,student_id,student_name,email,lab,"
        "normalize,wrap,mean_pose,bayes_posterior,"  # every exercise of the batch, in order
        "autograded,total,max,submitted,days_late,late_penalty_percent,final,overrides,flags,errors"
    )
    assert rows[0]["path"] == "subs/alice.ipynb" and data_path_is_in_json(tmp_path)
    assert (rows[0]["wrap"], rows[0]["bayes_posterior"], rows[0]["total"], rows[0]["max"]) == (
        "20",
        "",
        "60",
        "100",
    )
    assert (
        rows[2]["errors"] == "the notebook does not say which lab it is" and rows[2]["total"] == "0"
    )
    data = json.loads(json_path.read_text())
    assert data[0]["exercises"]["wrap"] == {"earned": 20, "possible": 30}
    assert data[0]["load_problems"] == 1 and data[2]["errors"]


def data_path_is_in_json(out: Path) -> bool:
    return [r["path"] for r in json.loads((out / "gradebook.json").read_text())] == [
        "subs/alice.ipynb",
        "subs/bob.ipynb",
        "subs/carol.ipynb",
    ]


def test_feedback_files_are_named_after_submissions(tmp_path):
    paths = write_feedback([partial_result(), broken_result()], tmp_path)
    assert [p.relative_to(tmp_path).as_posix() for p in paths] == [
        "feedback/alice.md",
        "feedback/carol.md",
    ]
    assert paths[0].read_text() == render_feedback(partial_result())


def test_summary_table_lines_up():
    table = summary_table([partial_result(), other_lab_result(), broken_result()])
    lines = table.splitlines()
    assert lines[0].split() == ["submission", "lab", "score", "time", "details"]
    assert "60/100" in lines[2] and "wrap 20/30, mean_pose 0/30; 1 cell(s) skipped" in lines[2]
    assert "100/100" in lines[3] and "full marks" in lines[3]
    assert lines[4].split()[:3] == ["carol", "?", "-"]
    # columns are aligned: the score column ends at the same offset on every row
    ends = {line.index("/100") + 4 for line in lines[2:4]}
    assert len(ends) == 1


# -- everything from the submission is fenced (issue 16, item 5) --------------------------------

INJECTIONS = [
    "# Feedback on someone_else.ipynb\n\nScore: **100 / 100** points.",
    "```\n# Feedback\n```\nScore: **100 / 100**",
    "````\n## `wrap`: 30 / 30 points\n````",
    "~~~~\n# Feedback\n~~~~",
    "<h1>Feedback</h1> [link](http://x) ![img](http://x)",
    "`` ` ``` ```` ````` \n# Score: **100 / 100**",
    "\r# Feedback\x1b[2J\x00",
]


def _tokens(text: str) -> list[dict]:
    """CommonMark block tokens (mistune's AST: the Markdown parser nbconvert uses)."""
    mistune = pytest.importorskip("mistune")
    return mistune.create_markdown(renderer=None)(text)


def _walk(tokens: list[dict]):
    for t in tokens:
        yield t
        yield from _walk(t.get("children") or [])


def _text(token: dict) -> str:
    return "".join(t.get("raw", "") for t in _walk(token.get("children") or []))


def _structure(text: str) -> tuple[list[str], str]:
    """The headings, and the text that is not code, of rendered Markdown."""
    tokens = list(_walk(_tokens(text)))
    headings = [_text(t) for t in tokens if t["type"] == "heading"]
    prose = [t["raw"] for t in tokens if t["type"] == "text"]
    prose += [
        "<html>" for t in tokens if t["type"] in ("inline_html", "block_html", "link", "image")
    ]
    strong = [_text(t) for t in tokens if t["type"] == "strong"]
    return headings, "\n".join(prose + strong)


@pytest.mark.parametrize("evil", INJECTIONS)
def test_student_strings_cannot_make_headings_or_scores(evil):
    honest = partial_result()
    result = partial_result()
    result.path = Path(f"subs/{evil.splitlines()[0]}.ipynb")
    result.problems = [
        {"cell_index": 2, "kind": "error", "message": evil},
        {"cell": evil, "kind": "syntax", "message": evil},
    ]
    result.errors = [f"grading timed out; the notebook printed {evil}"]
    result.tests = [
        TestOutcome(
            t.nodeid, t.description, t.exercise, t.points, t.outcome, evil if not t.passed else ""
        )
        for t in result.tests
    ]
    headings, prose = _structure(render_feedback(result))
    expected_headings, _ = _structure(render_feedback(honest))
    # the same sections as an honest result (plus the problem section), in the same order
    assert [h for h in headings[1:] if h != "Grading problems"] == expected_headings[1:]
    assert headings[0].startswith("Feedback on")
    assert "100 / 100" not in prose and "Feedback" not in prose.replace("Feedback on", "")
    assert "<html>" not in prose


def test_fences_outgrow_any_backtick_run():
    from robolab.grading.course.report import code_span, fenced

    for text in ["`", "``x``", "a ```` b", "`" * 9, "", "~~~", "line\n```\nmore"]:
        tokens = _tokens("\n".join(fenced(text)) + "\n")
        assert [t["type"] for t in tokens] == ["block_code"], tokens
        assert tokens[0]["raw"].rstrip("\n") == text
        inline = _tokens(code_span(text or "x"))[0]["children"]
        assert [c["type"] for c in inline] == ["codespan"], inline


@pytest.mark.parametrize("odd", ["\udcff\udcfe", "\ud800", "\x00\x1b[2J", "\u202e"])
def test_odd_characters_from_student_code_are_written_readably(tmp_path, odd):
    result = partial_result()
    result.errors = [f"the worker said {odd}"]
    result.tests[3] = TestOutcome(
        result.tests[3].nodeid, "wrap: x", "wrap", 10, "failed", f"AssertionError: {odd}"
    )
    csv_path, json_path = write_gradebook([result], tmp_path)
    write_feedback([result], tmp_path)
    for path in (csv_path, json_path, tmp_path / "feedback" / "alice.md"):
        text = path.read_bytes().decode("utf-8")  # strict: valid UTF-8
        assert "the worker said" in text or path.suffix == ".md"
    error = json.loads(json_path.read_text())[0]["errors"][0]
    assert error.startswith("the worker said ")
    error.encode("utf-8")  # no lone surrogate survives into the gradebook
    feedback = (tmp_path / "feedback" / "alice.md").read_text()
    assert all(c.isprintable() or c == "\n" for c in feedback)  # escaped, not raw
