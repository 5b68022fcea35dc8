"""Gradescope autograder bundles, and the grading step that runs inside one.

``build_bundle(lab, zip)`` writes a zip whose top level Gradescope unpacks into
``/autograder/source`` (and copies ``run_autograder`` to ``/autograder/``)::

    setup.sh          installs robolab from /autograder/source into /autograder/venv (run once)
    run_autograder    grades /autograder/submission/*.ipynb into /autograder/results/results.json
    robolab/ data/ pyproject.toml README.md
    solutions/<lab>.py tests/labs/test_<lab>.py   (this lab's answers and hidden tests only)

Inside the container ``python -m robolab.grading.gradescope run ...`` finds the
notebook, grades it with the same runner as ``robolab grade`` and writes
Gradescope's results format: ``{"score", "output", "tests": [{"name", "score",
"max_score", "status", "output"}]}``. Every path can be overridden (arguments,
or ``ROBOLAB_AUTOGRADER_DIR`` / ``ROBOLAB_PYTHON`` for ``run_autograder``), so the
bundle can be tried outside Gradescope.
"""

from __future__ import annotations

import argparse
import json
import sys
import zipfile
from pathlib import Path

from robolab.grading.labs import LabError, find_lab, lab_of_notebook, project_root
from robolab.grading.protection import require_answers_protected
from robolab.grading.report import render_feedback
from robolab.grading.runner import DEFAULT_TIMEOUT, SubmissionResult, grade_submission

__all__ = ["build_bundle", "find_submission", "results_json", "run"]

SETUP_SH = """\
#!/usr/bin/env bash
# Gradescope runs this once when it builds the autograder image (as root, in /autograder).
set -euo pipefail
if ! python3 -c 'import sys, venv; assert sys.version_info >= (3, 10)' 2>/dev/null; then
    apt-get update
    apt-get install -y --no-install-recommends python3 python3-venv python3-pip
fi
python3 -m venv /autograder/venv
/autograder/venv/bin/python -m pip install --quiet --upgrade pip
# Editable, so that robolab finds source/data and the hidden tests next to it.
/autograder/venv/bin/python -m pip install --quiet -e /autograder/source
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
exec "$PYTHON" -m robolab.grading.gradescope run --lab {lab} --root "$AUTOGRADER/source" \\
    --submission "$AUTOGRADER/submission" --results "$AUTOGRADER/results/results.json"
"""

_SKIP_DIRS = {"__pycache__", ".ipynb_checkpoints"}


def _add_tree(zf: zipfile.ZipFile, folder: Path, arcname: str) -> None:
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder)
        if path.is_file() and not _SKIP_DIRS & set(rel.parts) and path.suffix != ".pyc":
            zf.write(path, f"{arcname}/{rel.as_posix()}")


def _add_text(zf: zipfile.ZipFile, arcname: str, text: str, executable: bool = False) -> None:
    info = zipfile.ZipInfo(arcname)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = (0o755 if executable else 0o644) << 16
    zf.writestr(info, text)


def build_bundle(lab: str, out: Path, root: Path | None = None) -> Path:
    """Write the Gradescope autograder zip for ``lab`` to ``out`` and return ``out``.

    Raises
    ------
    LabError
        When the lab has no hidden tests or no reference solution.
    """
    spec = find_lab(lab, root)
    if not spec.solution.is_file():
        raise LabError(f"lab {lab!r} has no reference solution: expected {spec.solution}")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        _add_text(zf, "setup.sh", SETUP_SH, executable=True)
        _add_text(zf, "run_autograder", RUN_AUTOGRADER.format(lab=lab), executable=True)
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
            _add_text(zf, f"{init}", "")
        zf.write(spec.solution, f"solutions/{lab}.py")
        zf.write(spec.hidden_tests, f"tests/labs/test_{lab}.py")
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


def results_json(result: SubmissionResult) -> dict:
    """Gradescope's results format for one graded submission."""
    tests = [
        {
            "name": f"{t.exercise}: {t.description.removeprefix(f'{t.exercise}: ')}",
            "score": t.points if t.passed else 0.0,
            "max_score": t.points,
            "status": "passed" if t.passed else "failed",
            "output": t.message,
            "visibility": "visible",
        }
        for t in result.tests
    ]
    return {
        "score": result.total,
        "output": render_feedback(result),
        "output_format": "md",
        "visibility": "visible",
        "stdout_visibility": "hidden",
        "tests": tests,
    }


def run(
    lab: str,
    submission: Path,
    results: Path,
    root: Path | None = None,
    timeout: float = DEFAULT_TIMEOUT,
) -> dict:
    """Grade the submitted notebook and write ``results``; return what was written."""
    require_answers_protected()  # sandbox hook: never grade where workers can read the answers
    root = root or project_root()
    try:
        notebook = find_submission(submission, lab)
    except FileNotFoundError as exc:
        data = {"score": 0.0, "output": str(exc), "visibility": "visible", "tests": []}
    else:
        data = results_json(grade_submission(notebook, lab=lab, root=root, timeout=timeout))
    results.parent.mkdir(parents=True, exist_ok=True)
    results.write_text(json.dumps(data, indent=1))
    return data


def main(argv: list[str] | None = None) -> int:
    """``python -m robolab.grading.gradescope run --lab NAME ...``: what ``run_autograder`` runs."""
    p = argparse.ArgumentParser(prog="python -m robolab.grading.gradescope")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="grade one Gradescope submission")
    r.add_argument("--lab", required=True)
    r.add_argument(
        "--root", type=Path, default=None, help="folder holding solutions/ and tests/labs/"
    )
    r.add_argument("--submission", type=Path, default=Path("/autograder/submission"))
    r.add_argument("--results", type=Path, default=Path("/autograder/results/results.json"))
    r.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT)
    args = p.parse_args(argv)
    data = run(args.lab, args.submission, args.results, root=args.root, timeout=args.timeout)
    print(f"robolab: {args.lab}: {data['score']:g} points; results in {args.results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
