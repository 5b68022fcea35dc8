"""Grade files that learning-management systems import.

- **Canvas** (Grades > Import, "How do I import grades in the Gradebook?" in the Canvas
  Instructor Guide): a CSV whose first columns are ``Student, ID, SIS User ID, SIS Login
  ID, Section`` followed by one column per assignment, named after it; Canvas finds
  the student by ``ID`` (Canvas user id), ``SIS User ID`` or ``SIS Login ID`` and
  ignores ``Student``. We write the roster's ``canvas_id`` (may be empty), its ``id``
  as SIS User ID and ``sis_login_id`` (or the email) as SIS Login ID.
- **Moodle** (Grades > Import > CSV file, docs.moodle.org "Grade import"): any CSV with
  a header; on import the instructor maps the user by "Email address" (to ``email``) or
  "ID number" (to ``idnumber``) and the grade column to a grade item; a feedback column
  can be mapped to that item's feedback.

Every cell goes through :func:`robolab.grading.course.spreadsheet.csv_text`: roster text
a spreadsheet would evaluate (``=HYPERLINK(...)``) gets a leading single quote, which
neither LMS uses to match students (real ids and emails never start with ``= + - @``);
scores stay plain numbers. A student without a submission gets an empty cell, not a
zero; a student with several submissions gets the best final score (the gradebook
flags them).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from robolab.grading.course.batch import atomic_write
from robolab.grading.course.roster import Student
from robolab.grading.course.spreadsheet import csv_text

__all__ = ["EXPORTS", "canvas_csv", "moodle_csv", "write_export"]

CANVAS_COLUMNS = ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]


def _best(rows: Sequence[dict]) -> dict[str, dict]:
    best: dict[str, dict] = {}
    for row in rows:
        sid = row.get("student_id")
        if sid and (sid not in best or row["final"] > best[sid]["final"]):
            best[sid] = row
    return best


def _points(row: dict | None) -> str:
    return "" if row is None else f"{row['final']:g}"


def canvas_csv(rows: Sequence[dict], students: Sequence[Student], assignment: str) -> str:
    """The Canvas gradebook import CSV for one assignment column."""
    best = _best(rows)
    return csv_text(
        [
            [*CANVAS_COLUMNS, assignment],
            *(
                [
                    s.name,
                    s.canvas_id,
                    s.id,
                    s.sis_login_id or s.email,
                    s.section,
                    _points(best.get(s.id)),
                ]
                for s in students
            ),
        ]
    )


def moodle_csv(rows: Sequence[dict], students: Sequence[Student], assignment: str) -> str:
    """A Moodle grade import CSV: ID number, email, name, the grade and its feedback."""
    best = _best(rows)
    table = [["ID number", "Email address", "Full name", assignment, "Feedback"]]
    for s in students:
        row = best.get(s.id)
        note = "" if row is None else f"{row['final']:g} / {row['max']:g} points (robolab)"
        table.append([s.id, s.email, s.name, _points(row), note])
    return csv_text(table)


EXPORTS = {"canvas": canvas_csv, "moodle": moodle_csv}


def write_export(
    kind: str, rows: Sequence[dict], students: Sequence[Student], assignment: str, out: Path
) -> Path:
    """Write ``out/<kind>.csv`` atomically and return its path."""
    if kind not in EXPORTS:
        raise ValueError(f"unknown export {kind!r}; choose from {', '.join(EXPORTS)}")
    path = Path(out) / f"{kind}.csv"
    atomic_write(path, EXPORTS[kind](rows, students, assignment))
    return path
