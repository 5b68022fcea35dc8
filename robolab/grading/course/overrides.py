"""Manual grades: an instructor's points for one exercise of one student, kept across regrades.

An overrides file is a CSV with the columns ``student,exercise,points,comment``:
``student`` is a roster id or a submission name, ``exercise`` an exercise function's
name, ``points`` the points that exercise earns instead of the autograded ones (0 to
the exercise's maximum). The batch keeps its copy in ``<out>/overrides.csv`` and
applies it every time the gradebook is written, after autograding, so a regrade never
loses a manual grade; ``robolab grade --overrides FILE`` replaces that copy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from robolab.grading.course.roster import RosterError, read_csv

__all__ = ["Override", "apply_overrides", "read_overrides"]


@dataclass(frozen=True)
class Override:
    """One manual grade."""

    student: str
    exercise: str
    points: float
    comment: str = ""


def read_overrides(path: Path) -> list[Override]:
    """Read and check an overrides CSV (points >= 0; one row per student and exercise)."""
    found, seen = [], set()
    for line, row in enumerate(read_csv(path, ("student", "exercise", "points")), start=2):
        where = f"{path}, line {line}"
        if not row["student"] or not row["exercise"]:
            raise RosterError(f"{where}: empty student or exercise")
        try:
            points = float(row["points"])
        except ValueError:
            raise RosterError(f"{where}: points {row['points']!r} is not a number") from None
        if not points >= 0 or points == float("inf"):
            raise RosterError(f"{where}: points must be a non-negative number, got {points}")
        if (row["student"], row["exercise"]) in seen:
            raise RosterError(
                f"{where}: a second override of {row['exercise']} for {row['student']}"
            )
        seen.add((row["student"], row["exercise"]))
        found.append(Override(row["student"], row["exercise"], points, row.get("comment", "")))
    return found


def apply_overrides(
    scores: dict[str, tuple[float, float]], overrides: Sequence[Override]
) -> tuple[dict[str, tuple[float, float]], list[str], list[str]]:
    """Apply one submission's overrides to its ``{exercise: (earned, possible)}``.

    Returns the new scores, a line per applied override (``wrap: 20 -> 30 (comment)``)
    and a line per override that could not apply (unknown exercise, points above the
    maximum).
    """
    scores = dict(scores)
    applied, refused = [], []
    for o in overrides:
        if o.exercise not in scores:
            refused.append(f"override of {o.exercise!r}: no such exercise in this submission")
            continue
        earned, possible = scores[o.exercise]
        if o.points > possible:
            refused.append(
                f"override of {o.exercise!r}: {o.points:g} points is more than its {possible:g}"
            )
            continue
        scores[o.exercise] = (o.points, possible)
        note = f" ({o.comment})" if o.comment else ""
        applied.append(f"{o.exercise}: {earned:g} -> {o.points:g}{note}")
    return scores, applied, refused
