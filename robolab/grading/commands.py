"""The grading sub-commands of ``robolab``: grade, check, solve, release, gradescope.

Each returns the process exit code and prints what the user needs; the work is
in :mod:`~robolab.grading.runner`, :mod:`~robolab.grading.report`,
:mod:`~robolab.grading.solve`, :mod:`~robolab.grading.release` and
:mod:`~robolab.grading.gradescope`.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import sys
from collections.abc import Sequence
from pathlib import Path

from robolab.grading.labs import LabError, find_lab

__all__ = ["check", "grade", "gradescope", "release", "solve"]

#: Exit code when a command could not do its job (as opposed to a low score).
FAILED = 2


def _error(message: str) -> int:
    print(f"robolab: error: {message}", file=sys.stderr)
    return FAILED


def grade(
    submissions: Sequence[Path],
    *,
    lab: str | None = None,
    out: Path = Path("grades"),
    jobs: int = 1,
    timeout: float | None = None,
    progress: bool = True,
) -> int:
    """Grade notebooks into ``out`` (gradebook.csv, gradebook.json, feedback/) and print a summary.

    Exit 0 whenever grading ran, whatever the scores; 2 when it could not
    (unknown lab, pytest missing, hidden tests that do not run).
    """
    from robolab.grading.report import summary_table, write_feedback, write_gradebook
    from robolab.grading.runner import DEFAULT_TIMEOUT, grade_all

    if importlib.util.find_spec("pytest") is None:
        return _error("pytest is not installed in this environment; it runs the hidden tests")
    if not submissions:
        return _error("no submissions given")
    if lab is not None:
        try:
            find_lab(lab)
        except LabError as exc:
            return _error(str(exc))
    try:
        results = grade_all(
            list(submissions),
            lab=lab,
            jobs=jobs,
            timeout=timeout or DEFAULT_TIMEOUT,
            progress=progress,
        )
    except ValueError as exc:
        return _error(str(exc))
    csv_path, json_path = write_gradebook(results, out)
    write_feedback(results, out)
    print(summary_table(results))
    print(f"\ngradebook: {csv_path} and {json_path}; feedback: {out / 'feedback'}/")
    fatal = [r for r in results if r.fatal]
    for r in fatal:
        print(
            f"robolab: grading could not run for {r.path}: {'; '.join(r.errors)}", file=sys.stderr
        )
    return FAILED if fatal else 0


def check(notebook: Path) -> int:
    """Run the visible checks of the notebook's lab on the student's own functions.

    The notebook is loaded exactly as ``robolab grade`` loads it (the same
    cells, run whole and in order, with the same load limit per cell), but in
    this process: on a student's machine it is the student's own code, so no
    isolation is needed (grading isolates, checking does not). Exit 0 when
    every visible check passed, 1 when one failed, 2 when the notebook cannot
    be checked.
    """
    from robolab.checks.base import CheckFailed
    from robolab.grading.notebook import load_notebook

    try:
        loaded = load_notebook(Path(notebook))
    except Exception as exc:  # any reading problem is the student's to fix: say it plainly
        return _error(f"cannot read {notebook}: {exc}")
    if not loaded.lab:
        return _error(f"{notebook} does not say which lab it is (no robolab.lab in its metadata)")
    try:
        checks = importlib.import_module(f"robolab.checks.{loaded.lab}")
    except ModuleNotFoundError:
        return _error(f"lab {loaded.lab!r} has no visible checks")
    # The same cells, run the same way, as `robolab grade` runs them in its worker.
    from robolab.grading.kernel import load_budget, new_namespace, run_cells
    from robolab.grading.proxy import Limits

    namespace = new_namespace("__notebook__")
    budget = load_budget(Limits().wall_seconds, Limits().cpu_seconds)
    problems = list(loaded.problems)
    problems += [loaded.problem(*failed) for failed in run_cells(namespace, loaded.cells, *budget)]
    for p in sorted(problems, key=lambda p: p.cell_index):
        print(f"note: {p}")
    visible = sorted(
        (
            f
            for name, f in inspect.getmembers(checks, inspect.isfunction)
            if name.startswith("check_") and f.__module__ == checks.__name__
        ),
        key=lambda f: inspect.getsourcelines(f)[1],
    )
    failures = 0
    for check_fn in visible:
        exercise = check_fn.__name__.removeprefix("check_")
        func = namespace.get(exercise)
        if not callable(func):
            print(
                f"\u2718 {exercise}: not defined in your notebook "
                "(keep the name from the exercise cell)"
            )
            failures += 1
            continue
        try:
            check_fn(func)
        except CheckFailed as exc:
            print(f"\u2718 {exc}")
            failures += 1
    if failures:
        print(f"{failures} of {len(visible)} visible checks failed.")
        return 1
    print("visible checks passed (the graded tests are stronger: test your edge cases too).")
    return 0


def solve(notebooks: Sequence[Path], *, out: Path) -> int:
    """Write solved copies of the notebooks (or of every notebook in given folders) to ``out``."""
    from robolab.grading.solve import SolveError, solve_paths

    try:
        written = solve_paths(list(notebooks), out)
    except (SolveError, LabError) as exc:
        return _error(str(exc))
    print(f"solved {len(written)} notebook(s) into {out}/")
    return 0


def release(out: Path) -> int:
    """Build the student edition into ``out``."""
    from robolab.grading.release import ReleaseError, build_release

    try:
        build_release(out)
    except (ReleaseError, SyntaxError) as exc:
        return _error(str(exc))
    print(f"student edition written to {out}/ (no solutions, no hidden tests)")
    return 0


def gradescope(lab: str, *, out: Path) -> int:
    """Build the Gradescope autograder zip for ``lab``."""
    from robolab.grading.gradescope import build_bundle

    try:
        build_bundle(lab, out)
    except LabError as exc:
        return _error(str(exc))
    print(f"Gradescope autograder for lab {lab!r}: {out}")
    return 0
