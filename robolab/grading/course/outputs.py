"""One batch's outputs: the autograded results joined with the course's roster, late policy
and manual overrides, written as the gradebook, feedback, LMS exports and class report.

:class:`Course` is what ``robolab grade`` publishes after every finished submission
(gradebook and that submission's feedback) and at the end (all feedback, stale
feedback removed, exports, the class report ``report.html``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from robolab.grading.course.batch import BatchState, atomic_write, relative_paths
from robolab.grading.course.class_report import write_class_report
from robolab.grading.course.late import LatePolicy, submission_time
from robolab.grading.course.lms import write_export
from robolab.grading.course.overrides import Override, read_overrides
from robolab.grading.course.report import (
    Context,
    gradebook_rows,
    remove_stale_feedback,
    summary_table,
    write_feedback,
    write_gradebook,
)
from robolab.grading.course.roster import Student, match_submissions
from robolab.grading.running.runner import SubmissionResult

__all__ = ["OVERRIDES_FILE", "Course"]

#: The batch's own copy of the manual overrides, applied on every publish.
OVERRIDES_FILE = "overrides.csv"


class Course:
    """The course data of a batch writing into ``out``.

    Parameters
    ----------
    out, state
        The output folder and its :class:`~robolab.grading.course.batch.BatchState`.
    students
        The roster, or None.
    overrides
        Overrides given on this run (they replace ``out/overrides.csv``), or None to
        use that file when it exists.
    policy, times
        The late policy and the timestamp rows (None: file modification times).
    modified
        Modification times by submission name, used instead of the files' own when
        ``times`` is None (a merge of shards, whose files may be on other machines).
    """

    def __init__(
        self,
        out: Path,
        state: BatchState,
        students: list[Student] | None,
        overrides: list[Override] | None,
        policy: LatePolicy | None,
        times: list | None,
        *,
        exports: Sequence[str] = (),
        assignment: str | None = None,
        modified: dict | None = None,
    ):
        self.out, self.state = Path(out), state
        self.modified = modified or {}
        self.students, self.policy, self.times = students, policy, times
        self.exports, self.assignment = tuple(exports), assignment
        stored = self.out / OVERRIDES_FILE
        if overrides is None and stored.is_file():
            overrides = read_overrides(stored)
        self.overrides = overrides or []

    def keep_overrides(self, source: Path) -> None:
        """Make ``source`` the batch's overrides file (kept for later regrades)."""
        target = self.out / OVERRIDES_FILE
        if not (target.exists() and target.samefile(source)):
            atomic_write(target, Path(source).read_text(encoding="utf-8-sig"))

    def context(self) -> Context:
        """Roster matches and lateness for every submission the batch remembers."""
        keys = list(self.state.entries)
        names = [self.state.entries[k]["result"]["name"] for k in keys]
        relative = dict(zip(names, relative_paths(keys), strict=True))
        roster = match_submissions(self.students, relative) if self.students is not None else None
        lateness = {}
        if self.policy is not None:
            for key, name in zip(keys, names, strict=True):
                if self.times is None and name in self.modified:
                    when = self.modified[name]
                else:
                    when = submission_time(Path(key), relative[name], self.times)
                lateness[name] = self.policy.lateness(when)
        return Context(roster=roster, lateness=lateness, overrides=self.overrides)

    def publish(
        self, changed: SubmissionResult | None = None, *, final: bool = False, report: bool = True
    ) -> dict[str, Path]:
        """Rewrite the gradebook; write ``changed``'s feedback, or (``final``) every
        submission's feedback, remove stale feedback and write the exports and (unless
        ``report`` is False: an interrupted batch stops at once) the class report."""
        results = self.state.results()
        context = self.context()
        write_gradebook(results, self.out, context)
        if changed is not None:
            write_feedback([changed], self.out, context)
        if not final and changed is not None:
            return {}
        write_feedback(results, self.out, context)
        remove_stale_feedback(self.out, [r.name for r in results])
        if not final:
            return {}
        rows = gradebook_rows(results, context)
        written = {"class report": write_class_report(results, rows, self.out)} if report else {}
        if self.students is None:
            return written
        assignment = self.assignment or ", ".join(sorted({r.lab for r in results if r.lab}))
        for kind in self.exports:
            written[kind] = write_export(
                kind, rows, self.students, assignment or "robolab", self.out
            )
        return written

    def summary(self, results: Sequence[SubmissionResult]) -> str:
        """The summary table of ``results``, then what the instructor must look at."""
        context = self.context()
        lines = [summary_table(results)]
        rows = {row["submission"]: row for row in gradebook_rows(results, context)}
        flagged = [(name, row["flags"]) for name, row in rows.items() if row["flags"]]
        if flagged:
            lines += ["", f"FLAGGED: {len(flagged)} submission(s) need a look:"]
            lines += [f"  {name}: {'; '.join(flags)}" for name, flags in flagged]
        if any(row["overrides"] for row in rows.values()):
            lines += ["", "manual overrides applied:"]
            lines += [
                f"  {name}: {'; '.join(row['overrides'])}"
                for name, row in rows.items()
                if row["overrides"]
            ]
        if self.policy is not None:
            late = [(n, r) for n, r in rows.items() if r["days_late"]]
            lines += ["", f"late: {len(late)} submission(s)"]
            lines += [
                f"  {n}: {r['days_late']} day(s), -{r['late_penalty_percent']:g}%" for n, r in late
            ]
        if context.roster is not None:
            unmatched = context.roster.unmatched
            missing = context.roster.missing
            lines += [
                "",
                f"submissions without a student: {len(unmatched)}"
                + (f" ({', '.join(unmatched)})" if unmatched else ""),
                f"students without a submission: {len(missing)}"
                + (f" ({', '.join(f'{s.id} {s.name}' for s in missing)})" if missing else ""),
            ]
        return "\n".join(lines)
