"""What grading produces: the gradebook, per-submission feedback and the summary table.

Feedback is for students: it names each failing check in words (the hidden
test's docstring) with the failure's message, expected against got. It never
quotes the hidden tests' code: the messages come from the grading report, which
keeps only exception messages and the student's own traceback.

Every string that can come from a submission (file names, load problems, exception
messages, output) is put in a code span or a fenced block whose fence is longer than
any backtick run inside it, so it can never make a heading, a score or a link.

A gradebook row is the autograded result, then (when the batch has them) the student
from the roster, manual overrides, and the late penalty: ``total`` is the autograded
points with overrides, ``final`` is ``total`` after the late penalty.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from robolab.grading.course.batch import atomic_write, display_path
from robolab.grading.course.late import Lateness
from robolab.grading.course.overrides import Override, apply_overrides
from robolab.grading.course.roster import RosterMatch
from robolab.grading.course.spreadsheet import csv_text
from robolab.grading.running.runner import SubmissionResult, TestOutcome

__all__ = [
    "MEASURED_COLUMNS",
    "Context",
    "code_span",
    "fenced",
    "gradebook_rows",
    "remove_stale_feedback",
    "render_feedback",
    "summary_table",
    "write_feedback",
    "without_measured",
    "write_gradebook",
]

#: Gradebook columns that say how long grading took, not what a submission earned: two
#: gradings of the same files (sharded or not, on another machine) differ in them only.
MEASURED_COLUMNS = ("seconds", "cpu_seconds")


@dataclass
class Context:
    """What the course adds to the autograded results (all optional)."""

    roster: RosterMatch | None = None
    lateness: dict[str, Lateness] = field(default_factory=dict)  # by submission name
    overrides: list[Override] = field(default_factory=list)

    def overrides_for(self, result: SubmissionResult) -> list[Override]:
        student = self.roster.student_of.get(result.name) if self.roster else None
        ids = {result.name, *([student.id] if student else [])}
        return [o for o in self.overrides if o.student in ids]


def _pts(x: float) -> str:
    return f"{x:g}"


def _printable(text: str) -> str:
    """Bytes that were not UTF-8 as ``\\xNN``, control characters (newlines too) as escapes."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in display_path(str(text)))


def code_span(text: str) -> str:
    """``text`` as one Markdown code span that nothing inside can end early."""
    text = _printable(text)
    ticks = "`" * (max((len(m) for m in re.findall(r"`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") or not text.strip() else ""
    return f"{ticks}{pad}{text}{pad}{ticks}"


def fenced(text: str) -> list[str]:
    """``text`` as a fenced code block whose backtick fence is longer than any run inside."""
    longest = max((len(m) for m in re.findall(r"`{3,}", text)), default=0)
    fence = "`" * max(3, longest + 1)
    lines = display_path(text).splitlines()
    return [f"{fence}text", *(_printable(line) for line in lines), fence]


def _exercise_columns(results: Sequence[SubmissionResult]) -> list[str]:
    columns: list[str] = []
    for r in results:
        columns += [e for e in r.exercise_scores() if e not in columns]
    return columns


def _row(r: SubmissionResult, context: Context) -> dict:
    scores, applied, refused = apply_overrides(r.exercise_scores(), context.overrides_for(r))
    total = sum(got for got, _ in scores.values())
    late = context.lateness.get(r.name)
    student = context.roster.student_of.get(r.name) if context.roster else None
    flags = _flags(r) + refused + (context.roster.flags(r.name) if context.roster else [])
    return {
        "submission": r.name,
        "path": display_path(r.path),
        "student_id": student.id if student else None,
        "student_name": student.name if student else None,
        "email": student.email if student else None,
        "lab": r.lab,
        "exercises": {e: {"earned": got, "possible": of} for e, (got, of) in scores.items()},
        "autograded": r.total,
        "total": total,
        "max": r.max_points,
        "submitted": late.submitted.isoformat() if late and late.submitted else None,
        "days_late": late.days_late if late else 0,
        "late_penalty_percent": late.penalty_percent if late else 0.0,
        "final": late.apply(total) if late else total,
        "overrides": [display_path(o) for o in applied],
        "flags": [display_path(f) for f in flags],
        "errors": [display_path(e) for e in r.errors],
        "load_problems": len(r.problems),
        "seconds": round(r.seconds, 2),
        "cpu_seconds": round(r.cpu_seconds, 2),
        "isolation": r.isolation,
    }


def without_measured(rows: Sequence[dict]) -> list[dict]:
    """Copies of gradebook ``rows`` without the :data:`MEASURED_COLUMNS`."""
    return [{k: v for k, v in r.items() if k not in MEASURED_COLUMNS} for r in rows]


def gradebook_rows(
    results: Sequence[SubmissionResult], context: Context | None = None
) -> list[dict]:
    """One JSON-ready row per submission."""
    context = context or Context()
    return [_row(r, context) for r in results]


_CSV_HEAD = ["submission", "path", "student_id", "student_name", "email", "lab"]
_CSV_TAIL = [
    "autograded",
    "total",
    "max",
    "submitted",
    "days_late",
    "late_penalty_percent",
    "final",
    "overrides",
    "flags",
    "errors",
]


def write_gradebook(
    results: Sequence[SubmissionResult], out: Path, context: Context | None = None
) -> tuple[Path, Path]:
    """Write ``out/gradebook.csv`` and ``out/gradebook.json`` (atomically); return their paths.

    The CSV has one column per exercise seen in the batch (empty for a
    submission of another lab) between the identity and the totals.
    """
    out.mkdir(parents=True, exist_ok=True)
    rows = gradebook_rows(results, context)
    json_path, csv_path = out / "gradebook.json", out / "gradebook.csv"
    exercises = _exercise_columns(results)
    # The isolation column only when the sandbox left something unprotected (then on every row).
    tail = _CSV_TAIL + (["isolation"] if any(r.isolation for r in results) else [])
    table = [[*_CSV_HEAD, *exercises, *tail]]
    for row in rows:
        per = [
            _pts(row["exercises"][e]["earned"]) if e in row["exercises"] else "" for e in exercises
        ]
        cells = {
            k: "; ".join(v) if isinstance(v, list) else _pts(v) if isinstance(v, float) else v
            for k, v in row.items()
        }
        table.append([*(cells[k] for k in _CSV_HEAD), *per] + [cells.get(k) for k in tail])
    atomic_write(json_path, json.dumps(rows, indent=1) + "\n")
    atomic_write(csv_path, csv_text(table))  # no cell a spreadsheet would evaluate
    return csv_path, json_path


def _not_implemented(test: TestOutcome) -> bool:
    return test.message.lstrip().startswith(("NotImplementedError", "StudentNotImplementedError"))


def _check_name(test: TestOutcome) -> str:
    return (
        test.description.removeprefix(f"{test.exercise}: ").strip()
        or test.nodeid.rsplit("::", 1)[-1]
    )


def _problem_line(p: dict) -> list[str]:
    index = p.get("cell_index")
    fallback = f"cell {index + 1}" if isinstance(index, int) and index >= 0 else "the notebook"
    where = p.get("where") or p.get("cell") or fallback  # 1-based, as a student finds it
    return [
        f"- {code_span(str(where))} ({code_span(str(p.get('kind', 'problem')))}):",
        "",
        *(f"  {s}" for s in fenced(str(p.get("message", "")))),
        "",
    ]


def render_feedback(result: SubmissionResult, row: dict | None = None) -> str:
    """The Markdown feedback for one submission (``row``: its gradebook row, for overrides
    and the late penalty)."""
    lines = [f"# Feedback on {code_span(result.path.name)}", ""]
    if result.lab:
        lines.append(f"Lab: {code_span(result.lab)}.")
    if result.tests:
        lines.append(f"Score: **{_pts(result.total)} / {_pts(result.max_points)}** points.")
    lines.append("")
    if row and (row["overrides"] or row["days_late"]):
        lines += ["## Adjustments", ""]
        lines += [f"- instructor: {code_span(o)}" for o in row["overrides"]]
        if row["days_late"]:
            lines.append(
                f"- handed in {row['days_late']} day(s) late: -{_pts(row['late_penalty_percent'])}%"
            )
        lines += ["", f"Final: **{_pts(row['final'])} / {_pts(row['max'])}** points.", ""]
    if result.errors:
        lines += ["## Grading problems", ""]
        for e in result.errors:
            lines += ["- problem:", "", *(f"  {s}" for s in fenced(e)), ""]
    if result.problems:
        lines += [
            "## Problems loading your notebook",
            "",
            "These cells were skipped when your functions were loaded:",
            "",
        ]
        for p in result.problems:
            lines += _problem_line(p)
    for exercise, (got, of) in result.exercise_scores().items():
        lines += [f"## {code_span(exercise)}: {_pts(got)} / {_pts(of)} points", ""]
        failing = [t for t in result.tests if t.exercise == exercise and not t.passed]
        if not failing:
            lines += ["Every hidden check of this function passed.", ""]
            continue
        if all(_not_implemented(t) for t in failing) and got == 0:
            lines += [
                f"Not implemented yet: {code_span(exercise)} still raises NotImplementedError.",
                "",
            ]
            continue
        for t in failing:
            what = {
                "failed": "failed",
                "error": "could not run",
                "skipped": "was skipped",
                "not run": "did not run",
            }.get(t.outcome, t.outcome)
            lines.append(f"- **{_check_name(t)}** ({_pts(t.points)} points) {what}:")
            # every line indented, so that the block stays inside its list item
            lines += ["", *(f"  {s}".rstrip() for s in fenced(t.message or "(no message)")), ""]
    return "\n".join(lines).rstrip() + "\n"


def write_feedback(
    results: Sequence[SubmissionResult], out: Path, context: Context | None = None
) -> list[Path]:
    """Write ``out/feedback/<submission>.md`` for each result (atomically); return the paths."""
    folder = out / "feedback"
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for r, row in zip(results, gradebook_rows(results, context), strict=True):
        path = folder / f"{r.name}.md"
        atomic_write(path, render_feedback(r, row))
        paths.append(path)
    return paths


def remove_stale_feedback(out: Path, names: Sequence[str]) -> list[Path]:
    """Delete ``out/feedback/*.md`` files of no current submission; return them."""
    keep = {f"{n}.md" for n in names}
    stale = [p for p in (out / "feedback").glob("*.md") if p.name not in keep]
    for p in stale:
        p.unlink()
    return stale


def _flags(r: SubmissionResult) -> list[str]:
    """The result's flags, a limit that cut it short among them."""
    return [*r.flags, *(f"limit: {line}" for line in r.limits)]


def _details(r: SubmissionResult) -> str:
    if flags := _flags(r):
        more = f" (+{len(flags) - 1} more)" if len(flags) > 1 else ""
        return "FLAG: " + _printable(flags[0]) + more
    if r.errors:
        note = _printable(r.errors[0].splitlines()[0] if r.errors[0].strip() else r.errors[0])
        return note if len(note) <= 70 else note[:67] + "..."
    short = [f"{e} {_pts(g)}/{_pts(o)}" for e, (g, o) in r.exercise_scores().items() if g < o]
    text = ", ".join(short) if short else "full marks"
    return text + (f"; {len(r.problems)} cell(s) skipped" if r.problems else "")


def summary_table(results: Sequence[SubmissionResult]) -> str:
    """A plain-text table: submission, lab, score, and what cost points."""
    rows = [("submission", "lab", "score", "time", "details")]
    for r in results:
        score = f"{_pts(r.total)}/{_pts(r.max_points)}" if r.tests else "-"
        rows.append((r.name, _printable(r.lab or "?"), score, f"{r.seconds:.1f}s", _details(r)))
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines = []
    for k, row in enumerate(rows):
        lines.append(
            "  ".join(
                [
                    row[0].ljust(widths[0]),
                    row[1].ljust(widths[1]),
                    row[2].rjust(widths[2]),
                    row[3].rjust(widths[3]),
                    row[4],
                ]
            ).rstrip()
        )
        if k == 0:
            lines.append("  ".join("-" * w for w in widths) + "  " + "-" * 7)
    return "\n".join(lines)
