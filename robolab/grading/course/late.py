"""The late policy: a due date, a penalty per started day late, and a cap.

A submission handed in ``d`` seconds after the due date is ``ceil(d / 86400)`` days
late and loses ``min(days * penalty_per_day, cap)`` percent of its points. The time a
submission was handed in comes from a timestamp CSV (``match,submitted``: the same
``match`` as in the roster), from the file's modification time, or from Gradescope's
``submission_metadata.json`` (``created_at``; the due date is the assignment's
``due_date``). Times are ISO 8601; one without a time zone is taken as UTC.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from robolab.grading.course.roster import RosterError, matches, read_csv

__all__ = ["LatePolicy", "Lateness", "parse_time", "read_times", "submission_time"]


def parse_time(text: str, what: str = "time") -> datetime:
    """An aware datetime from ISO 8601 text (``Z`` accepted; no zone means UTC)."""
    try:
        value = datetime.fromisoformat(text.strip().replace("Z", "+00:00").replace("z", "+00:00"))
    except ValueError:
        raise RosterError(
            f"{what} {text!r} is not an ISO 8601 time (like 2026-03-01T23:59:00+01:00)"
        ) from None
    return value if value.tzinfo else value.replace(tzinfo=timezone.utc)


@dataclass(frozen=True)
class Lateness:
    """When a submission came in and what that costs."""

    submitted: datetime | None
    days_late: int
    penalty_percent: float

    def apply(self, points: float) -> float:
        """``points`` after the penalty."""
        return round(points * (1 - self.penalty_percent / 100), 4)


@dataclass(frozen=True)
class LatePolicy:
    """A due date with a penalty (percent of the points) per started day late, capped."""

    due: datetime
    penalty_per_day: float = 0.0
    cap: float = 100.0

    def __post_init__(self):
        if self.due.tzinfo is None:
            raise ValueError("the due date needs a time zone")
        if not 0 <= self.penalty_per_day <= 100:
            raise ValueError(f"penalty per day must be 0-100 percent, got {self.penalty_per_day}")
        if not 0 <= self.cap <= 100:
            raise ValueError(f"penalty cap must be 0-100 percent, got {self.cap}")

    def lateness(self, submitted: datetime | None) -> Lateness:
        """What handing in at ``submitted`` costs (None: unknown time, no penalty)."""
        if submitted is None or submitted <= self.due:
            return Lateness(submitted, 0, 0.0)
        days = math.ceil((submitted - self.due).total_seconds() / 86400)
        return Lateness(submitted, days, min(days * self.penalty_per_day, self.cap))


def read_times(path: Path) -> list[tuple[str, datetime]]:
    """``(match, submitted)`` pairs from a timestamp CSV with columns ``match,submitted``."""
    rows = read_csv(path, ("match", "submitted"), {"submission": "match", "timestamp": "submitted"})
    return [
        (row["match"], parse_time(row["submitted"], f"{path}, line {line}: submitted"))
        for line, row in enumerate(rows, start=2)
    ]


def submission_time(
    path: Path, relative: str, times: list[tuple[str, datetime]] | None
) -> datetime | None:
    """When the submission came in: the first matching row of ``times``, else its mtime."""
    if times is not None:
        for pattern, when in times:
            if matches(pattern, relative):
                return when
        return None
    try:
        return datetime.fromtimestamp(os.stat(path).st_mtime, tz=timezone.utc)
    except OSError:
        return None
