"""Gradescope autograder bundles, and the grading step that runs inside one.

``build_bundle(lab, zip)`` writes a zip whose top level Gradescope unpacks into
``/autograder/source`` (and copies ``run_autograder`` to ``/autograder/``)::

    setup.sh          installs robolab and pytest into /autograder/venv; makes solutions/ and
                      tests/ readable by root only; checks the result (run once, as root)
    run_autograder    grades /autograder/submission/*.ipynb into /autograder/results/results.json
    robolab-gradescope.json   per-exercise test visibility and the late policy
    robolab/ data/ pyproject.toml README.md
    solutions/<lab>.py tests/labs/test_<lab>.py   (this lab's answers and hidden tests only)

Inside the container ``python -m robolab.grading.exports.gradescope run ...`` finds the
notebook, grades it with the same runner as ``robolab grade`` and writes
Gradescope's results format (https://gradescope-autograders.readthedocs.io/en/latest/specs/):
``{"score", "output", "output_format", "visibility", "stdout_visibility", "execution_time",
"extra_data", "tests": [{"name", "name_format", "score", "max_score", "status", "output",
"output_format", "visibility"}]}``. It reads ``/autograder/submission_metadata.json``
(``users``: who submitted; ``created_at`` and ``assignment.due_date``: the late policy and
whether the due date has passed). Every path can be overridden (arguments, or
``ROBOLAB_AUTOGRADER_DIR`` / ``ROBOLAB_PYTHON`` for the scripts), so the bundle can be
tried outside Gradescope.

The worker runs student code as a uid of its own (the container runs the grader as
root), which cannot read root's 0700 ``solutions/`` and ``tests/`` even where Linux
namespaces and Landlock are unavailable. ``run`` refuses to grade when the answers are
readable by the worker.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import stat
import sys
import time
import zipfile
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

from robolab.grading.course.late import LatePolicy, parse_time
from robolab.grading.course.report import render_feedback
from robolab.grading.course.roster import RosterError
from robolab.grading.isolation.protection import UnprotectedAnswers, describe_protection
from robolab.grading.labs import LabError, find_lab, lab_of_notebook, project_root
from robolab.grading.running.runner import DEFAULT_TIMEOUT, SubmissionResult, grade_submission

__all__ = [
    "VISIBILITIES",
    "BundleOptions",
    "answers_exposed",
    "is_bundle",
    "build_bundle",
    "find_submission",
    "results_json",
    "run",
]

#: Gradescope's visibility values for a test or the whole result.
VISIBILITIES = ("visible", "after_due_date", "after_published", "hidden")
OPTIONS_FILE = "robolab-gradescope.json"

SETUP_SH = """\
#!/usr/bin/env bash
# Gradescope runs this once when it builds the autograder image (as root, in /autograder).
set -euo pipefail
AUTOGRADER="${ROBOLAB_AUTOGRADER_DIR:-/autograder}"
SOURCE="$AUTOGRADER/source"
VENV="$AUTOGRADER/venv"
PYTHON3="${ROBOLAB_SETUP_PYTHON:-python3}"
if ! "$PYTHON3" -c 'import sys, venv, ensurepip; assert sys.version_info >= (3, 10)' \\
        2>/dev/null; then
    apt-get update
    apt-get install -y --no-install-recommends python3 python3-venv python3-pip
    PYTHON3=python3
fi
"$PYTHON3" -m venv "$VENV"
# robolab (editable, so that it finds source/data and the hidden tests next to it) and
# pytest, which runs the hidden tests, and nbformat (the instructor extra's, without copydetect).
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -e "$SOURCE" "pytest>=8.0" "nbformat>=5.9"
# The answers: root only. Everything the worker needs: readable by every uid.
if [ "$(id -u)" = 0 ]; then chown -R 0:0 "$SOURCE/solutions" "$SOURCE/tests"; fi
chmod -R go-rwx "$SOURCE/solutions" "$SOURCE/tests"
chmod -R a+rX "$VENV" "$SOURCE/robolab" "$SOURCE/pyproject.toml"
if [ -d "$SOURCE/data" ]; then chmod -R a+rX "$SOURCE/data"; fi
chmod a+rx "$AUTOGRADER" "$SOURCE"
# Fail the image build now, not every submission later, when something is missing.
"$VENV/bin/python" -m robolab.grading.exports.gradescope check --root "$SOURCE"
"""

RUN_AUTOGRADER = """\
#!/usr/bin/env bash
# Gradescope runs this for each submission; it writes results/results.json.
set -euo pipefail
AUTOGRADER="${{ROBOLAB_AUTOGRADER_DIR:-/autograder}}"
PYTHON="${{ROBOLAB_PYTHON:-$AUTOGRADER/venv/bin/python}}"
mkdir -p "$AUTOGRADER/results"
cd "$AUTOGRADER/source"
export ROBOLAB_ROOT="$AUTOGRADER/source"
exec "$PYTHON" -m robolab.grading.exports.gradescope run --lab {lab} --root "$AUTOGRADER/source" \\
    --submission "$AUTOGRADER/submission" --results "$AUTOGRADER/results/results.json" \\
    --metadata "$AUTOGRADER/submission_metadata.json"
"""


@dataclass(frozen=True)
class BundleOptions:
    """How a bundle shows its tests and treats late submissions.

    ``visibility`` maps an exercise to the Gradescope visibility of its tests
    (``default_visibility`` for the others). A failing test that is not ``visible``
    never shows its message in the overall feedback, and an ``after_due_date`` or
    ``hidden`` test shows it in its own output only once the due date has passed
    (``hidden``: never). ``late_penalty`` is percent per started day after the
    assignment's due date (from submission_metadata.json), capped at ``late_cap``.
    """

    visibility: dict[str, str] = field(default_factory=dict)
    default_visibility: str = "visible"
    late_penalty: float = 0.0
    late_cap: float = 100.0

    def __post_init__(self):
        for v in (*self.visibility.values(), self.default_visibility):
            if v not in VISIBILITIES:
                raise ValueError(f"visibility {v!r}: choose from {', '.join(VISIBILITIES)}")
        LatePolicy(datetime.now(timezone.utc), self.late_penalty, self.late_cap)  # checks ranges

    def of(self, exercise: str) -> str:
        return self.visibility.get(exercise, self.default_visibility)

    @classmethod
    def read(cls, root: Path) -> BundleOptions:
        path = Path(root) / OPTIONS_FILE
        return cls(**json.loads(path.read_text())) if path.is_file() else cls()


_SKIP_DIRS = {"__pycache__", ".ipynb_checkpoints"}


def _add_tree(zf: zipfile.ZipFile, folder: Path, arcname: str) -> None:
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder)
        if path.is_file() and not _SKIP_DIRS & set(rel.parts) and path.suffix != ".pyc":
            zf.write(path, f"{arcname}/{rel.as_posix()}")


def _add_text(
    zf: zipfile.ZipFile, arcname: str, text: str, executable: bool = False, private: bool = False
) -> None:
    info = zipfile.ZipInfo(arcname)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = (0o600 if private else 0o755 if executable else 0o644) << 16
    zf.writestr(info, text)


def is_bundle(path: Path) -> bool:
    """Whether ``path`` is a zip that :func:`build_bundle` wrote (a file it may replace)."""
    try:
        with zipfile.ZipFile(path) as zf:
            return {"setup.sh", "run_autograder", OPTIONS_FILE} <= set(zf.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def build_bundle(
    lab: str, out: Path, root: Path | None = None, *, options: BundleOptions | None = None
) -> Path:
    """Write the Gradescope autograder zip for ``lab`` to ``out`` and return ``out``.

    The answers (solutions/, tests/) are stored with mode 0600 in the zip; setup.sh
    makes them root's in the image whatever the unpacking did.

    Raises
    ------
    LabError
        When the lab has no hidden tests or no reference solution.
    ValueError
        When ``out`` exists and is not such a bundle (it is never replaced).
    """
    spec = find_lab(lab, root)
    if not spec.solution.is_file():
        raise LabError(f"lab {lab!r} has no reference solution: expected {spec.solution}")
    options = options or BundleOptions()
    graded = set(re.findall(r"""grades\(\s*["'](\w+)["']""", spec.hidden_tests.read_text()))
    unknown = sorted(set(options.visibility) - graded)
    if unknown:
        raise LabError(
            f"--visibility names {', '.join(unknown)}, which lab {lab!r} does not grade "
            f"(its exercises: {', '.join(sorted(graded))})"
        )
    out = Path(out)
    if out.exists() and not is_bundle(out):
        raise ValueError(
            f"{out} exists and is not a Gradescope autograder bundle; refusing to replace "
            "it (move it away or choose another name)"
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        _add_text(zf, "setup.sh", SETUP_SH, executable=True)
        _add_text(zf, "run_autograder", RUN_AUTOGRADER.format(lab=lab), executable=True)
        _add_text(zf, OPTIONS_FILE, json.dumps(asdict(options), indent=1) + "\n")
        _add_tree(zf, spec.root / "robolab", "robolab")
        if (spec.root / "data").is_dir():
            _add_tree(zf, spec.root / "data", "data")
        zf.write(spec.root / "pyproject.toml", "pyproject.toml")
        readme = spec.root / "README.md"
        _add_text(
            zf,
            "README.md",
            readme.read_text() if readme.is_file() else "# robolab autograder\n",
        )
        for init in ("solutions/__init__.py", "tests/__init__.py", "tests/labs/__init__.py"):
            _add_text(zf, f"{init}", "", private=True)
        _add_text(zf, f"solutions/{lab}.py", spec.solution.read_text(), private=True)
        _add_text(zf, f"tests/labs/test_{lab}.py", spec.hidden_tests.read_text(), private=True)
    return out


def find_submission(folder: Path, lab: str) -> Path:
    """The one notebook in ``folder`` (searched recursively) to grade for ``lab``.

    Raises
    ------
    FileNotFoundError
        When there is no notebook, or several and none is unambiguously of ``lab``.
    """
    found = sorted(p for p in Path(folder).rglob("*.ipynb") if ".ipynb_checkpoints" not in p.parts)
    if len(found) == 1:
        return found[0]
    if not found:
        raise FileNotFoundError(f"no .ipynb notebook was submitted (looked in {folder})")
    of_lab = []
    for p in found:
        try:
            if lab_of_notebook(p) == lab:
                of_lab.append(p)
        except LabError:
            continue
    if len(of_lab) == 1:
        return of_lab[0]
    names = ", ".join(p.name for p in found)
    raise FileNotFoundError(
        f"several notebooks were submitted ({names}); submit only the one for lab {lab!r}"
    )


def answers_exposed(root: Path) -> list[str]:
    """Why the worker could read the answers under ``root`` (empty: it cannot).

    Two checks, both must pass. The sandbox's probe
    (:func:`robolab.grading.isolation.protection.describe_protection`) starts a real worker and
    tries to open a solution and a hidden test. And the files themselves: a root
    grader's workers run as an unprivileged uid of their own, so the answers stay
    protected even without namespaces or Landlock when no file or folder under
    ``solutions/`` and ``tests/`` is readable by others (or reachable); a grader that
    is not root relies on Landlock.
    """
    paths = [Path(root) / "solutions", Path(root) / "tests"]
    protection = describe_protection()
    probed = (
        []
        if protection.answers_protected
        else list(protection.problems or ["a sandboxed worker could read the answers"])
    )
    return probed + _readable_answer_files(paths)


def _readable_answer_files(paths: list[Path]) -> list[str]:
    """Answer files that a worker's uid could read if no sandbox layer held."""
    if os.geteuid() != 0:
        from robolab.grading.isolation.sandbox import landlock_abi

        return (
            []
            if landlock_abi() > 0
            else [
                "the grader is not root and Landlock is unavailable: the worker runs as the "
                "grader's own uid and can read the answers"
            ]
        )
    reasons = []
    for top in paths:
        if not top.exists():
            continue
        for path in [top, *sorted(top.rglob("*"))]:
            mode = path.lstat().st_mode
            readable = mode & stat.S_IROTH
            if readable and _reachable_by_others(path.parent):
                reasons.append(f"{path} is readable by every user (mode {stat.filemode(mode)})")
    return reasons


def _reachable_by_others(folder: Path) -> bool:
    for directory in [folder, *folder.parents]:
        if not directory.stat().st_mode & stat.S_IXOTH:
            return False
    return True


def read_metadata(path: Path | None) -> dict:
    """Gradescope's submission_metadata.json, or {} when there is none or it is unreadable."""
    if path is None or not Path(path).is_file():
        return {}
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _due_date(metadata: dict) -> datetime | None:
    """The due date that applies: a user's own (an extension) before the assignment's."""
    candidates = [
        u.get("assignment", {}).get("due_date")
        for u in metadata.get("users", []) or []
        if isinstance(u, dict) and isinstance(u.get("assignment"), dict)
    ]
    candidates.append((metadata.get("assignment") or {}).get("due_date"))
    for text in candidates:
        if isinstance(text, str) and text:
            try:
                return parse_time(text, "due_date")
            except RosterError:
                continue
    return None


def _submitted_at(metadata: dict) -> datetime | None:
    text = metadata.get("created_at")
    try:
        return parse_time(text, "created_at") if isinstance(text, str) else None
    except RosterError:
        return None


def results_json(
    result: SubmissionResult,
    options: BundleOptions | None = None,
    metadata: dict | None = None,
    now: datetime | None = None,
) -> dict:
    """Gradescope's results format for one graded submission.

    Test names and outputs are plain text (``name_format``/``output_format`` "text"),
    so nothing a submission prints can format them; the overall output is the Markdown
    feedback, in which every string from the submission is fenced, restricted to the
    ``visible`` tests.
    """
    options = options or BundleOptions()
    metadata = metadata or {}
    now = now or datetime.now(timezone.utc)
    due = _due_date(metadata)
    past_due = due is not None and now >= due
    tests = []
    for t in result.tests:
        visibility = options.of(t.exercise)
        output = t.message
        if not t.passed and (visibility == "hidden" or (visibility != "visible" and not past_due)):
            output = "This check failed; its details are not shown" + (
                "." if visibility == "hidden" else " before the due date."
            )
        tests.append(
            {
                "name": f"{t.exercise}: {t.description.removeprefix(f'{t.exercise}: ')}",
                "name_format": "text",
                "score": t.points if t.passed else 0.0,
                "max_score": t.points,
                "status": "passed" if t.passed else "failed",
                "output": output if not t.passed else "",
                "output_format": "text",
                "visibility": visibility,
            }
        )
    shown = replace(result, tests=[t for t in result.tests if options.of(t.exercise) == "visible"])
    score = result.total
    lines = [render_feedback(shown)]
    if len(shown.tests) < len(result.tests):
        held = sum(t.points for t in result.tests if t not in shown.tests)
        lines.append(f"\n{held:g} more points are graded by checks that are not shown here.\n")
    extra: dict = {}
    if options.late_penalty and due is not None:
        lateness = LatePolicy(due, options.late_penalty, options.late_cap).lateness(
            _submitted_at(metadata)
        )
        if lateness.days_late:
            score = lateness.apply(score)
            lines.append(
                f"\nHanded in {lateness.days_late} day(s) after the due date: "
                f"-{lateness.penalty_percent:g}%, {score:g} points.\n"
            )
        extra["late"] = asdict(lateness) | {"submitted": str(lateness.submitted)}
    users = [u for u in metadata.get("users", []) or [] if isinstance(u, dict)]
    if users:
        extra["students"] = [{k: u.get(k) for k in ("id", "name", "email")} for u in users]
    if "id" in metadata:
        extra["submission_id"] = metadata["id"]
    return {
        "score": score,
        "execution_time": round(result.seconds),
        "output": "".join(lines),
        "output_format": "md",
        "visibility": "visible",
        "stdout_visibility": "hidden",
        "extra_data": extra,
        "tests": tests,
    }


def _write(results: Path, data: dict) -> None:
    results.parent.mkdir(parents=True, exist_ok=True)
    results.write_text(json.dumps(data, indent=1))


def run(
    lab: str,
    submission: Path,
    results: Path,
    root: Path | None = None,
    timeout: float = DEFAULT_TIMEOUT,
    metadata: Path | None = None,
) -> dict:
    """Grade the submitted notebook and write ``results``; return what was written.

    Raises
    ------
    PermissionError
        When the worker could read the answers (results.json then says so, score 0).
    """
    root = root or project_root()
    exposed = answers_exposed(root)
    if exposed:
        data = {
            "score": 0.0,
            "output": "The autograder is not set up safely, so it did not grade this "
            "submission; your instructor has been told. Please tell them too.",
            "visibility": "visible",
            "tests": [],
            "extra_data": {"refused": exposed},
        }
        _write(results, data)
        reasons = "; ".join(exposed)
        raise UnprotectedAnswers(
            f"robolab refuses to grade: the worker could read the answers: {reasons}"
        )
    started = time.monotonic()
    try:
        notebook = find_submission(submission, lab)
    except FileNotFoundError as exc:
        data = {"score": 0.0, "output": str(exc), "visibility": "visible", "tests": []}
    else:
        result = grade_submission(notebook, lab=lab, root=root, timeout=timeout)
        result.seconds = result.seconds or time.monotonic() - started
        data = results_json(result, BundleOptions.read(root), read_metadata(metadata))
    _write(results, data)
    return data


def check(root: Path) -> list[str]:
    """What keeps this bundle from grading (empty: ready): pytest missing, answers exposed."""
    import importlib.util

    problems = []
    for module in ("pytest", "nbformat", "numpy"):
        if importlib.util.find_spec(module) is None:
            problems.append(f"{module} is not installed in {sys.prefix}")
    return problems + answers_exposed(root)


def main(argv: list[str] | None = None) -> int:
    """``python -m robolab.grading.exports.gradescope run|check``: the bundle scripts' command."""
    p = argparse.ArgumentParser(prog="python -m robolab.grading.exports.gradescope")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="grade one Gradescope submission")
    r.add_argument("--lab", required=True)
    r.add_argument(
        "--root", type=Path, default=None, help="folder holding solutions/ and tests/labs/"
    )
    r.add_argument("--submission", type=Path, default=Path("/autograder/submission"))
    r.add_argument("--results", type=Path, default=Path("/autograder/results/results.json"))
    r.add_argument("--metadata", type=Path, default=Path("/autograder/submission_metadata.json"))
    r.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT)
    c = sub.add_parser("check", help="is this installation ready to grade?")
    c.add_argument("--root", type=Path, default=None)
    args = p.parse_args(argv)
    if args.command == "check":
        problems = check(args.root or project_root())
        for problem in problems:
            print(f"robolab: error: {problem}", file=sys.stderr)
        if not problems:
            print("robolab: the autograder is ready (pytest installed, answers root-only)")
        return 1 if problems else 0
    try:
        data = run(
            args.lab,
            args.submission,
            args.results,
            root=args.root,
            timeout=args.timeout,
            metadata=args.metadata,
        )
    except PermissionError as exc:
        print(f"robolab: error: refusing to grade: {exc}", file=sys.stderr)
        return 1
    print(f"robolab: {args.lab}: {data['score']:g} points; results in {args.results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
