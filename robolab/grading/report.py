"""What grading produces: the gradebook, per-submission feedback and the summary table.

Feedback is for students: it names each failing check in words (the hidden
test's docstring) with the failure's message, expected against got. It never
quotes the hidden tests' code: the messages come from the grading report, which
keeps only exception messages and the student's own traceback.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

from robolab.grading.runner import SubmissionResult, TestOutcome

__all__ = ["render_feedback", "summary_table", "write_feedback", "write_gradebook"]


def _pts(x: float) -> str:
    return f"{x:g}"


def _exercise_columns(results: Sequence[SubmissionResult]) -> list[str]:
    columns: list[str] = []
    for r in results:
        columns += [e for e in r.exercise_scores() if e not in columns]
    return columns


def gradebook_rows(results: Sequence[SubmissionResult]) -> list[dict]:
    """One JSON-ready row per submission."""
    return [
        {
            "submission": r.name,
            "path": str(r.path),
            "lab": r.lab,
            "exercises": {
                e: {"earned": got, "possible": of} for e, (got, of) in r.exercise_scores().items()
            },
            "total": r.total,
            "max": r.max_points,
            "errors": list(r.errors),
            "load_problems": len(r.problems),
            "seconds": round(r.seconds, 2),
        }
        for r in results
    ]


def write_gradebook(results: Sequence[SubmissionResult], out: Path) -> tuple[Path, Path]:
    """Write ``out/gradebook.csv`` and ``out/gradebook.json``; return their paths.

    The CSV has one column per exercise seen in the batch (empty for a
    submission of another lab), then total, max and errors.
    """
    out.mkdir(parents=True, exist_ok=True)
    rows = gradebook_rows(results)
    json_path, csv_path = out / "gradebook.json", out / "gradebook.csv"
    json_path.write_text(json.dumps(rows, indent=1) + "\n")
    exercises = _exercise_columns(results)
    with csv_path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["submission", "lab", *exercises, "total", "max", "errors"])
        for row in rows:
            per = [
                _pts(row["exercises"][e]["earned"]) if e in row["exercises"] else ""
                for e in exercises
            ]
            w.writerow(
                [
                    row["submission"],
                    row["lab"] or "",
                    *per,
                    _pts(row["total"]),
                    _pts(row["max"]),
                    "; ".join(row["errors"]),
                ]
            )
    return csv_path, json_path


def _fenced(text: str) -> list[str]:
    fence = "~~~~"  # unlikely in student output, unlike ```
    return [fence, text.replace(fence, "~ ~ ~ ~"), fence]


def _not_implemented(test: TestOutcome) -> bool:
    return test.message.lstrip().startswith(("NotImplementedError", "StudentNotImplementedError"))


def _check_name(test: TestOutcome) -> str:
    return (
        test.description.removeprefix(f"{test.exercise}: ").strip()
        or test.nodeid.rsplit("::", 1)[-1]
    )


def render_feedback(result: SubmissionResult) -> str:
    """The Markdown feedback for one submission."""
    lines = [f"# Feedback on {result.path.name}", ""]
    if result.lab:
        lines.append(f"Lab: `{result.lab}`.")
    if result.tests:
        lines.append(f"Score: **{_pts(result.total)} / {_pts(result.max_points)}** points.")
    lines.append("")
    if result.errors:
        lines += ["## Grading problems", ""]
        lines += [f"- {e}" for e in result.errors]
        lines.append("")
    if result.problems:
        lines += [
            "## Problems loading your notebook",
            "",
            "These cells were skipped when your functions were loaded:",
            "",
        ]
        for p in result.problems:
            lines.append(
                f"- {p.get('where') or 'cell ' + str(p.get('cell_index', '?'))} "
                f"({p.get('kind', 'problem')}): "
                f"{p.get('message', '')}"
            )
        lines.append("")
    for exercise, (got, of) in result.exercise_scores().items():
        lines += [f"## `{exercise}`: {_pts(got)} / {_pts(of)} points", ""]
        failing = [t for t in result.tests if t.exercise == exercise and not t.passed]
        if not failing:
            lines += ["Every hidden check of this function passed.", ""]
            continue
        if all(_not_implemented(t) for t in failing) and got == 0:
            lines += [f"Not implemented yet: `{exercise}` still raises NotImplementedError.", ""]
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
            block = "\n".join(_fenced(t.message or "(no message)")).splitlines()
            lines += ["", *(f"  {s}".rstrip() for s in block), ""]
    return "\n".join(lines).rstrip() + "\n"


def write_feedback(results: Sequence[SubmissionResult], out: Path) -> list[Path]:
    """Write ``out/feedback/<submission>.md`` for each result; return the paths."""
    folder = out / "feedback"
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for r in results:
        path = folder / f"{r.name}.md"
        path.write_text(render_feedback(r))
        paths.append(path)
    return paths


def _details(r: SubmissionResult) -> str:
    if r.errors:
        note = r.errors[0].splitlines()[0]
        return note if len(note) <= 70 else note[:67] + "..."
    short = [f"{e} {_pts(g)}/{_pts(o)}" for e, (g, o) in r.exercise_scores().items() if g < o]
    text = ", ".join(short) if short else "full marks"
    return text + (f"; {len(r.problems)} cell(s) skipped" if r.problems else "")


def summary_table(results: Sequence[SubmissionResult]) -> str:
    """A plain-text table: submission, lab, score, and what cost points."""
    rows = [("submission", "lab", "score", "time", "details")]
    for r in results:
        score = f"{_pts(r.total)}/{_pts(r.max_points)}" if r.tests else "-"
        rows.append((r.name, r.lab or "?", score, f"{r.seconds:.1f}s", _details(r)))
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
