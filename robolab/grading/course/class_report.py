"""The class report: ``report.html`` beside the gradebook, for the instructor.

What to re-teach and what to look at, per lab: the distribution of the final points and
of every exercise's points (matplotlib figures, inline as base64 PNG so the file is
self-contained and opens without a server), the hidden checks failed most often (how
many students failed each, and its title), and the submissions flagged (late, cut short
by a limit, unprotected by the sandbox, another lab than expected, grading errors).

Every text that can come from a submission (names, paths, flags, messages) is escaped
with :func:`html.escape`; the page holds no script and loads nothing.
"""

from __future__ import annotations

import base64
import html
import io
from collections import Counter, defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from robolab.grading.course.batch import atomic_write
from robolab.grading.course.report import _check_name
from robolab.grading.running.runner import SubmissionResult

__all__ = ["REPORT_FILE", "failed_checks", "render_class_report", "write_class_report"]

#: The class report's file name in the batch's output folder.
REPORT_FILE = "report.html"
_TOP_CHECKS = 15

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 70em; color: #222; }
h1 { font-size: 1.6em; } h2 { margin-top: 2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 1em 0; }
th, td { border: 1px solid #ccc; padding: 0.3em 0.6em; text-align: left; vertical-align: top; }
th { background: #f3f3f3; } td.n { text-align: right; font-variant-numeric: tabular-nums; }
code { background: #f6f6f6; padding: 0 0.2em; } img { max-width: 100%; }
.bar { display: inline-block; height: 0.8em; background: #c0392b; }
.muted { color: #777; }
"""


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _pts(x: float) -> str:
    return f"{x:g}"


def failed_checks(results: Sequence[SubmissionResult]) -> list[dict]:
    """The hidden checks failed by at least one submission, most failed first.

    Returns
    -------
    list of dict
        ``{"lab", "exercise", "title", "points", "failed", "graded"}``: ``failed`` of the
        ``graded`` submissions of that lab that ran the check did not pass it. Ordered by
        the share that failed, then the points the check is worth.
    """
    failed: Counter = Counter()
    graded: Counter = Counter()
    info = {}
    for r in results:
        for t in r.tests:
            key = (r.lab, t.exercise, t.nodeid)
            info.setdefault(key, (_check_name(t), t.points))
            graded[key] += 1
            failed[key] += not t.passed
    rows = [
        {
            "lab": lab,
            "exercise": exercise,
            "title": info[(lab, exercise, node)][0],
            "points": info[(lab, exercise, node)][1],
            "failed": n,
            "graded": graded[(lab, exercise, node)],
        }
        for (lab, exercise, node), n in failed.items()
        if n
    ]
    # most often failed first; among equals, the one that costs more points
    return sorted(
        rows, key=lambda r: (-r["failed"] / r["graded"], -r["failed"], -r["points"], r["title"])
    )


def _png(fig) -> str:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _histogram(ax, values: np.ndarray, top: float, title: str) -> None:
    """Points earned, binned over [0, top] (at most 20 bins, one per point when fewer)."""
    bins = np.linspace(0, top, int(min(20, max(top, 1))) + 1) if top > 0 else 1
    ax.hist(values, bins=bins, color="#2c7fb8", edgecolor="white")
    ax.set_title(title, fontsize=9)
    ax.set_xlim(0, top if top > 0 else 1)
    ax.set_ylabel("submissions", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.yaxis.get_major_locator().set_params(integer=True)


def _figures(lab_rows: list[dict]) -> str:
    """One PNG per lab: the final points, then each exercise's points (after overrides)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    exercises = list(dict.fromkeys(e for row in lab_rows for e in row["exercises"]))
    panels = 1 + len(exercises)
    cols = min(4, panels)
    rows = -(-panels // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.4 * rows), squeeze=False)
    top = max((row["max"] for row in lab_rows), default=0)
    finals = np.array([row["final"] for row in lab_rows], dtype=float)
    _histogram(axes[0, 0], finals, top, f"final points (of {_pts(top)})")
    for ax, exercise in zip(axes.flat[1:], exercises, strict=False):
        earned = np.array(
            [
                row["exercises"][exercise]["earned"]
                for row in lab_rows
                if exercise in row["exercises"]
            ]
        )
        possible = max(
            row["exercises"][exercise]["possible"]
            for row in lab_rows
            if exercise in row["exercises"]
        )
        _histogram(ax, earned, possible, f"{exercise} (of {_pts(possible)})")
    for ax in axes.flat[panels:]:
        ax.set_visible(False)
    fig.tight_layout()
    try:
        return _png(fig)
    finally:
        plt.close(fig)


def _flagged(rows: Sequence[dict]) -> list[tuple[dict, list[str]]]:
    found = []
    for row in rows:
        reasons = list(row["flags"])
        if row["days_late"]:
            reasons.append(
                f"late: {row['days_late']} day(s), -{_pts(row['late_penalty_percent'])}%"
            )
        if row.get("isolation"):
            reasons.append(f"isolation: {row['isolation']}")
        reasons += [f"error: {e.splitlines()[0] if e.strip() else e}" for e in row["errors"]]
        if reasons:
            found.append((row, reasons))
    return found


def _lab_section(lab: str, rows: list[dict], results: list[SubmissionResult]) -> list[str]:
    finals = np.array([row["final"] for row in rows], dtype=float)
    top = max((row["max"] for row in rows), default=0)
    parts = [
        f"<h2>Lab <code>{_e(lab)}</code></h2>",
        f"<p>{len(rows)} submission(s); final points: mean {np.mean(finals):.1f}, "
        f"median {np.median(finals):g}, lowest {finals.min():g}, highest {finals.max():g} "
        f"(of {_pts(top)}).</p>",
    ]
    if any(row["exercises"] for row in rows):
        parts.append(
            f'<img alt="distribution of the points of lab {_e(lab)}" '
            f'src="data:image/png;base64,{_figures(rows)}">'
        )
        averages = []
        for exercise in dict.fromkeys(e for row in rows for e in row["exercises"]):
            got = [row["exercises"][exercise] for row in rows if exercise in row["exercises"]]
            full = sum(g["earned"] >= g["possible"] for g in got)
            mean = np.mean([g["earned"] for g in got])
            averages.append(
                f"<tr><td><code>{_e(exercise)}</code></td><td class=n>{mean:.1f} / "
                f"{_pts(got[0]['possible'])}</td><td class=n>{full} of {len(got)}</td></tr>"
            )
        parts += [
            "<table><tr><th>exercise</th><th>mean points</th><th>full marks</th></tr>",
            *averages,
            "</table>",
        ]
    checks = failed_checks(results)[:_TOP_CHECKS]
    parts.append("<h3>Checks failed most often</h3>")
    if not checks:
        parts.append("<p>Every submission passed every hidden check.</p>")
    else:
        parts.append(
            "<table><tr><th>exercise</th><th>check</th><th>points</th>"
            "<th>students who failed it</th><th></th></tr>"
        )
        for c in checks:
            share = c["failed"] / c["graded"]
            parts.append(
                f"<tr><td><code>{_e(c['exercise'])}</code></td><td>{_e(c['title'])}</td>"
                f"<td class=n>{_pts(c['points'])}</td>"
                f"<td class=n>{c['failed']} of {c['graded']}</td>"
                f'<td><span class=bar style="width:{100 * share:.0f}px"></span></td></tr>'
            )
        parts.append("</table>")
    return parts


def render_class_report(results: Sequence[SubmissionResult], rows: Sequence[dict]) -> str:
    """The class report as one self-contained HTML page.

    Parameters
    ----------
    results
        The batch's results.
    rows
        Their gradebook rows (:func:`robolab.grading.course.report.gradebook_rows`), in the same
        order: the points after overrides and the late penalty, the flags.
    """
    if len(results) != len(rows):
        raise ValueError(f"render_class_report: {len(results)} results but {len(rows)} rows")
    by_lab: dict[str, list[int]] = defaultdict(list)
    for i, r in enumerate(results):
        by_lab[r.lab or "unknown"].append(i)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        "<title>robolab class report</title>",
        f"<style>{_STYLE}</style></head><body>",
        "<h1>Class report</h1>",
        f"<p>{len(results)} submission(s) in {len(by_lab)} lab(s): "
        + ", ".join(f"<code>{_e(lab)}</code> ({len(ix)})" for lab, ix in sorted(by_lab.items()))
        + ". Points are after manual overrides and the late penalty.</p>",
    ]
    for lab, index in sorted(by_lab.items()):
        parts += _lab_section(lab, [rows[i] for i in index], [results[i] for i in index])
    flagged = _flagged(rows)
    parts.append(f"<h2>Submissions flagged ({len(flagged)})</h2>")
    if not flagged:
        parts.append('<p class="muted">None.</p>')
    else:
        parts.append(
            "<table><tr><th>submission</th><th>student</th><th>lab</th>"
            "<th>final</th><th>why</th></tr>"
        )
        for row, reasons in flagged:
            who = row["student_name"] or row["student_id"] or ""
            parts.append(
                f"<tr><td><code>{_e(row['submission'])}</code></td><td>{_e(who)}</td>"
                f"<td>{_e(row['lab'] or '?')}</td><td class=n>{_pts(row['final'])}</td><td>"
                + "<br>".join(_e(x) for x in reasons)
                + "</td></tr>"
            )
        parts.append("</table>")
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def write_class_report(
    results: Sequence[SubmissionResult], rows: Sequence[dict], out: Path
) -> Path:
    """Write ``out/report.html`` (atomically); return its path."""
    path = Path(out) / REPORT_FILE
    atomic_write(path, render_class_report(results, rows))
    return path
