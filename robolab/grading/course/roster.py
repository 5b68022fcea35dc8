"""The course roster: who the students are, and which submission is whose.

A roster is a CSV file with a header row and one row per student::

    id,name,email,match[,section,canvas_id,sis_login_id]
    s001,Ada Lovelace,ada@example.edu,ada_*.ipynb
    s002,Alan Turing,alan@example.edu,123456

``match`` says how to find the student's submission: a file-name pattern (``*``, ``?``
and ``[...]`` as in the shell, case-insensitive, tried on the file name and on the path
relative to the batch's common folder), or a Gradescope submission id (digits only),
which matches a folder ``submission_<id>`` of a Gradescope export or a file named
``<id>.ipynb``. ``section``, ``canvas_id`` and ``sis_login_id`` are only used by the
Canvas export (:mod:`robolab.grading.course.lms`).
"""

from __future__ import annotations

import csv
import fnmatch
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["RosterError", "RosterMatch", "Student", "match_submissions", "read_roster", "matches"]

_REQUIRED = ("id", "name", "email", "match")
_OPTIONAL = ("section", "canvas_id", "sis_login_id")
_ALIASES = {"student_id": "id", "student": "name", "pattern": "match", "submission": "match"}


class RosterError(ValueError):
    """A roster (or another course CSV) that cannot be used as it is."""


@dataclass(frozen=True)
class Student:
    """One row of the roster."""

    id: str
    name: str
    email: str
    match: str
    section: str = ""
    canvas_id: str = ""
    sis_login_id: str = ""


def _key(header: str) -> str:
    return "_".join(header.strip().lower().split())


def read_csv(
    path: Path, required: Sequence[str], aliases: dict[str, str] | None = None
) -> list[dict]:
    """Rows of a course CSV as dicts with lower-case, alias-resolved keys.

    Raises
    ------
    RosterError
        When the file cannot be read or lacks a required column.
    """
    aliases = aliases or {}
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            reader = csv.DictReader(f)
            header = {h: aliases.get(_key(h), _key(h)) for h in reader.fieldnames or []}
            rows = [
                {header[k]: (v or "").strip() for k, v in row.items() if k in header}
                for row in reader
            ]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise RosterError(f"cannot read {path}: {exc}") from None
    missing = [c for c in required if c not in header.values()]
    if missing:
        raise RosterError(
            f"{path}: missing column(s) {', '.join(missing)} (the header must name "
            f"{', '.join(required)})"
        )
    return rows


def read_roster(path: Path) -> list[Student]:
    """Read and check a roster CSV (unique ids, no empty id, name or match)."""
    students, seen = [], set()
    for line, row in enumerate(read_csv(path, _REQUIRED, _ALIASES), start=2):
        empty = [c for c in ("id", "name", "match") if not row.get(c)]
        if empty:
            raise RosterError(f"{path}, line {line}: empty {', '.join(empty)}")
        if row["id"] in seen:
            raise RosterError(f"{path}, line {line}: student id {row['id']!r} appears twice")
        seen.add(row["id"])
        students.append(Student(**{k: row.get(k, "") for k in (*_REQUIRED, *_OPTIONAL)}))
    return students


def matches(pattern: str, relative: str) -> bool:
    """Whether a roster ``match`` value selects the submission at ``relative`` (a relative path)."""
    parts = Path(relative).parts
    if pattern.isdigit():
        stem = Path(relative).stem
        return stem == pattern or any(p in (pattern, f"submission_{pattern}") for p in parts)
    pattern = pattern.lower()
    return fnmatch.fnmatchcase(Path(relative).name.lower(), pattern) or fnmatch.fnmatchcase(
        Path(relative).as_posix().lower(), pattern
    )


@dataclass
class RosterMatch:
    """Submissions mapped to students.

    ``student_of`` maps a submission name to its student; ``unmatched`` are submissions
    without a student, ``missing`` students without a submission, ``ambiguous``
    submissions that several students' patterns select (left unassigned), ``several``
    students with more than one submission (student id -> submission names).
    """

    student_of: dict[str, Student] = field(default_factory=dict)
    unmatched: list[str] = field(default_factory=list)
    missing: list[Student] = field(default_factory=list)
    ambiguous: dict[str, list[str]] = field(default_factory=dict)
    several: dict[str, list[str]] = field(default_factory=dict)

    def flags(self, name: str) -> list[str]:
        """What the gradebook should say about one submission's student."""
        if name in self.ambiguous:
            return [f"roster: matched by several students ({', '.join(self.ambiguous[name])})"]
        student = self.student_of.get(name)
        if student is None:
            return ["roster: no student matches this submission"]
        if student.id in self.several:
            return [f"roster: student {student.id} has several submissions"]
        return []


def match_submissions(students: Sequence[Student], submissions: dict[str, str]) -> RosterMatch:
    """Map ``submissions`` (name -> path relative to the batch's common folder) to ``students``."""
    result = RosterMatch()
    taken: dict[str, list[str]] = {}
    for name, relative in submissions.items():
        who = [s for s in students if matches(s.match, relative)]
        if len(who) > 1:
            result.ambiguous[name] = [s.id for s in who]
        elif who:
            result.student_of[name] = who[0]
            taken.setdefault(who[0].id, []).append(name)
        else:
            result.unmatched.append(name)
    result.missing = [s for s in students if s.id not in taken]
    result.several = {sid: names for sid, names in taken.items() if len(names) > 1}
    return result
