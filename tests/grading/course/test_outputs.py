"""Roster, late policy, manual overrides and LMS exports: units, then one course end to end."""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from robolab.cli import main
from robolab.grading.course.late import LatePolicy, parse_time
from robolab.grading.course.lms import CANVAS_COLUMNS, canvas_csv, moodle_csv
from robolab.grading.course.overrides import apply_overrides, read_overrides
from robolab.grading.course.roster import (
    RosterError,
    Student,
    match_submissions,
    matches,
    read_roster,
)
from tests.grading.running.test_runner import SUBMISSIONS, make_root

UTC = timezone.utc


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


# -- roster ------------------------------------------------------------------------------------


def test_roster_matches_patterns_and_gradescope_ids(tmp_path):
    roster = read_roster(
        write(
            tmp_path / "r.csv",
            "Student ID,Name,Email,Match\n"
            "s1,Ada,ada@x.edu,ada_*.ipynb\n"
            "s2,Alan,alan@x.edu,123456\n"
            "s3,Grace,grace@x.edu,grace*\n"
            "s4,Kurt,kurt@x.edu,kurt.ipynb\n",
        )
    )
    assert [s.id for s in roster] == ["s1", "s2", "s3", "s4"]
    found = match_submissions(
        roster,
        {
            "ada": "ADA_lab1.ipynb",  # case-insensitive
            "alan": "submission_123456/lab.ipynb",  # a Gradescope export folder
            "grace-1": "grace1.ipynb",
            "grace-2": "late/grace2.ipynb",  # several submissions of one student
            "nobody": "mallory.ipynb",
        },
    )
    assert {k: s.id for k, s in found.student_of.items()} == {
        "ada": "s1",
        "alan": "s2",
        "grace-1": "s3",
        "grace-2": "s3",
    }
    assert found.unmatched == ["nobody"] and [s.id for s in found.missing] == ["s4"]
    assert found.several == {"s3": ["grace-1", "grace-2"]}
    assert found.flags("nobody") == ["roster: no student matches this submission"]
    assert "several submissions" in found.flags("grace-2")[0] and found.flags("ada") == []


def test_a_submission_two_students_match_is_assigned_to_neither():
    a = Student("a", "A", "a@x", "*lab*")
    b = Student("b", "B", "b@x", "bob*")
    found = match_submissions([a, b], {"s": "bob_lab.ipynb"})
    assert found.ambiguous == {"s": ["a", "b"]} and not found.student_of
    assert {s.id for s in found.missing} == {"a", "b"}


@pytest.mark.parametrize(
    "text, complaint",
    [
        ("id,name,email\ns1,A,a@x\n", "missing column"),
        ("id,name,email,match\ns1,A,a@x,a*\ns1,B,b@x,b*\n", "appears twice"),
        ("id,name,email,match\ns1,,a@x,a*\n", "empty name"),
        ("id,name,email,match\ns1,A,a@x,\n", "empty match"),
    ],
)
def test_bad_rosters_say_where(tmp_path, text, complaint):
    with pytest.raises(RosterError, match=complaint):
        read_roster(write(tmp_path / "r.csv", text))


def test_gradescope_id_does_not_match_a_longer_number():
    assert matches("1234", "submission_1234/x.ipynb") and matches("1234", "1234.ipynb")
    assert not matches("1234", "submission_12345/x.ipynb") and not matches("1234", "a1234.ipynb")


# -- late policy -------------------------------------------------------------------------------

DUE = datetime(2026, 3, 1, 23, 59, tzinfo=UTC)


@pytest.mark.parametrize(
    "delay, days, percent",
    [
        (timedelta(seconds=-1), 0, 0),
        (timedelta(0), 0, 0),
        (timedelta(seconds=1), 1, 10),
        (timedelta(days=1), 1, 10),
        (timedelta(days=1, seconds=1), 2, 20),
        (timedelta(days=3, hours=2), 4, 35),  # capped
        (timedelta(days=400), 400, 35),
    ],
)
def test_penalty_per_started_day_is_capped(delay, days, percent):
    late = LatePolicy(DUE, penalty_per_day=10, cap=35).lateness(DUE + delay)
    assert (late.days_late, late.penalty_percent) == (days, percent)
    assert late.apply(80) == pytest.approx(80 * (1 - percent / 100))


def test_penalty_never_decreases_with_time():
    policy = LatePolicy(DUE, penalty_per_day=7.5, cap=60)
    penalties = [policy.lateness(DUE + timedelta(hours=h)).penalty_percent for h in range(0, 400)]
    assert penalties == sorted(penalties) and max(penalties) == 60


def test_times_parse_with_zone_and_default_to_utc():
    assert parse_time("2026-03-01T23:59:00Z") == DUE
    assert parse_time("2026-03-01T23:59") == DUE
    assert parse_time("2026-03-02T00:59:00+01:00") == DUE
    with pytest.raises(RosterError, match="ISO 8601"):
        parse_time("tomorrow")
    with pytest.raises(ValueError):
        LatePolicy(DUE, penalty_per_day=120)


# -- overrides ---------------------------------------------------------------------------------


def test_overrides_replace_exercise_points_and_refuse_the_impossible(tmp_path):
    found = read_overrides(
        write(
            tmp_path / "o.csv",
            "student,exercise,points,comment\n"
            "s1,wrap,30,fixed by hand\n"
            "s1,mean_pose,31,too many\n"
            "s1,nonexistent,1,\n",
        )
    )
    scores = {"wrap": (20.0, 30.0), "mean_pose": (0.0, 30.0)}
    new, applied, refused = apply_overrides(scores, found)
    assert new == {"wrap": (30.0, 30.0), "mean_pose": (0.0, 30.0)}
    assert applied == ["wrap: 20 -> 30 (fixed by hand)"]
    assert len(refused) == 2 and "more than its 30" in refused[0] and "no such" in refused[1]
    assert scores["wrap"] == (20.0, 30.0)  # the autograded scores are not modified


@pytest.mark.parametrize(
    "row, complaint",
    [("s1,wrap,lots,", "not a number"), ("s1,wrap,-1,", "non-negative"), (",wrap,1,", "empty")],
)
def test_bad_overrides_are_refused(tmp_path, row, complaint):
    with pytest.raises(RosterError, match=complaint):
        read_overrides(write(tmp_path / "o.csv", f"student,exercise,points,comment\n{row}\n"))


# -- LMS exports -------------------------------------------------------------------------------

STUDENTS = [
    Student("s1", "Ada Lovelace", "ada@x.edu", "a*", section="A", canvas_id="101"),
    Student("s2", "Alan Turing", "alan@x.edu", "b*", sis_login_id="aturing"),
]
ROWS = [
    {"student_id": "s1", "final": 55.5, "max": 100},
    {"student_id": "s1", "final": 70.0, "max": 100},
    {"student_id": None, "final": 100.0, "max": 100},
]


def test_canvas_csv_has_the_import_columns():
    table = list(csv.reader(io.StringIO(canvas_csv(ROWS, STUDENTS, "Lab 1: Bayes"))))
    assert table[0] == [*CANVAS_COLUMNS, "Lab 1: Bayes"]
    assert CANVAS_COLUMNS == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]
    assert table[1] == ["Ada Lovelace", "101", "s1", "ada@x.edu", "A", "70"]  # best of two
    assert table[2] == ["Alan Turing", "", "s2", "aturing", "", ""]  # no submission: no change


def test_moodle_csv_identifies_by_idnumber_and_email():
    table = list(csv.DictReader(io.StringIO(moodle_csv(ROWS, STUDENTS, "Lab 1"))))
    assert [(r["ID number"], r["Email address"], r["Lab 1"]) for r in table] == [
        ("s1", "ada@x.edu", "70"),
        ("s2", "alan@x.edu", ""),
    ]


# -- one course, end to end --------------------------------------------------------------------


@pytest.fixture
def course(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBOLAB_ROOT", str(make_root(tmp_path / "root")))
    subs = tmp_path / "subs"
    subs.mkdir()
    for student, example in (("ada", "correct"), ("alan", "partial"), ("mallory", "wrong")):
        shutil.copy(SUBMISSIONS / f"{example}.ipynb", subs / f"{student}_demo.ipynb")
    on_time = datetime(2026, 3, 1, 12, tzinfo=UTC).timestamp()
    os.utime(subs / "ada_demo.ipynb", (on_time, on_time))
    late = (DUE + timedelta(days=1, hours=1)).timestamp()
    os.utime(subs / "alan_demo.ipynb", (late, late))
    write(
        tmp_path / "roster.csv",
        "id,name,email,match,section\n"
        "s1,Ada Lovelace,ada@x.edu,ada_*,A\n"
        "s2,Alan Turing,alan@x.edu,alan_*,B\n"
        "s3,Grace Hopper,grace@x.edu,grace_*,A\n",
    )
    write(
        tmp_path / "overrides.csv",
        "student,exercise,points,comment\ns2,mean_pose,15,partial credit\n",
    )
    return tmp_path, sorted(subs.glob("*.ipynb"))


def test_a_course_end_to_end(course, capsys):
    tmp, subs = course
    out = tmp / "grades"
    common = ["--out", str(out), "--roster", str(tmp / "roster.csv"), "--due", DUE.isoformat()]
    late = ["--late-penalty", "10", "--late-cap", "50"]
    args = ["grade", *map(str, subs), *common, *late, "--export", "canvas", "--export", "moodle"]
    assert main([*args, "--overrides", str(tmp / "overrides.csv"), "--assignment", "Demo"]) == 0
    printed = capsys.readouterr().out
    rows = {r["submission"]: r for r in json.loads((out / "gradebook.json").read_text())}
    ada, alan, mallory = rows["ada_demo"], rows["alan_demo"], rows["mallory_demo"]
    assert (ada["student_id"], ada["final"], ada["days_late"]) == ("s1", 100, 0)
    # alan: 60 autograded + 15 by hand on mean_pose = 75, then two days late at 10% a day
    assert (alan["autograded"], alan["total"], alan["days_late"]) == (60, 75, 2)
    assert alan["final"] == pytest.approx(60) and alan["late_penalty_percent"] == 20
    assert alan["overrides"] == ["mean_pose: 0 -> 15 (partial credit)"]
    assert alan["exercises"]["mean_pose"] == {"earned": 15, "possible": 30}
    assert mallory["student_id"] is None and "no student" in mallory["flags"][0]
    assert "submissions without a student: 1 (mallory_demo)" in printed
    assert "students without a submission: 1 (s3 Grace Hopper)" in printed
    feedback = (out / "feedback" / "alan_demo.md").read_text()
    assert (
        "partial credit" in feedback and "2 day(s) late" in feedback and "Final: **60" in feedback
    )

    canvas = list(csv.DictReader((out / "canvas.csv").open()))
    assert [(r["SIS User ID"], r["Demo"]) for r in canvas] == [
        ("s1", "100"),
        ("s2", "60"),
        ("s3", ""),
    ]
    moodle = list(csv.DictReader((out / "moodle.csv").open()))
    assert [(r["Email address"], r["Demo"]) for r in moodle][:2] == [
        ("ada@x.edu", "100"),
        ("alan@x.edu", "60"),
    ]

    # a regrade (alan resubmits the same work under the same name) without --overrides
    # keeps the manual grade: the batch kept its copy of the overrides
    (tmp / "overrides.csv").unlink()
    shutil.copy(SUBMISSIONS / "partial.ipynb", subs[0].parent / "alan_demo.ipynb")
    os.utime(subs[0].parent / "alan_demo.ipynb", (DUE.timestamp(),) * 2)  # now on time
    assert main(args) == 0
    rows = {r["submission"]: r for r in json.loads((out / "gradebook.json").read_text())}
    assert rows["alan_demo"]["total"] == 75 and rows["alan_demo"]["final"] == 75
    table = {r["submission"]: r for r in csv.DictReader((out / "gradebook.csv").open())}
    assert table["alan_demo"]["overrides"] == "mean_pose: 0 -> 15 (partial credit)"
    assert table["alan_demo"]["mean_pose"] == "15" and table["alan_demo"]["final"] == "75"
