"""The grading sub-commands of ``robolab``: grade, check, solve, release, gradescope.

Each returns the process exit code and prints what the user needs; the work is
in :mod:`~robolab.grading.running.runner`, :mod:`~robolab.grading.course.report`,
:mod:`~robolab.grading.exports.solve`, :mod:`~robolab.grading.exports.release` and
:mod:`~robolab.grading.exports.gradescope`.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import inspect
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from robolab.grading.labs import LabError, find_lab

__all__ = ["check", "data", "grade", "gradescope", "merge", "release", "similarity", "solve"]

#: Exit code when a command could not do its job (as opposed to a low score).
FAILED = 2


def _error(message: str) -> int:
    print(f"robolab: error: {message}", file=sys.stderr)
    return FAILED


#: The course options of grade and merge, and their defaults.
_COURSE_DEFAULTS = {
    "roster": None,
    "overrides": None,
    "exports": (),
    "assignment": None,
    "due": None,
    "late_penalty": 0.0,
    "late_cap": 100.0,
    "submitted_times": None,
}


def _course_inputs(
    roster: Path | None,
    overrides: Path | None,
    due: str | None,
    penalty: float,
    cap: float,
    times: Path | None,
    exports: Sequence[str],
):
    """Read every course file before grading, so a typo costs nothing."""
    from robolab.grading.course.late import LatePolicy, parse_time, read_times
    from robolab.grading.course.overrides import read_overrides
    from robolab.grading.course.roster import read_roster

    if exports and roster is None:
        raise ValueError(f"--export {exports[0]} needs --roster (who the students are)")
    if (times is not None or penalty or cap != 100) and due is None:
        raise ValueError("--late-penalty, --late-cap and --submitted-times need --due")
    students = read_roster(roster) if roster is not None else None
    manual = read_overrides(overrides) if overrides is not None else None
    policy = (
        LatePolicy(parse_time(due, "--due"), penalty_per_day=penalty, cap=cap)
        if due is not None
        else None
    )
    stamps = read_times(times) if times is not None else None
    return students, manual, policy, stamps


def grade(
    submissions: Sequence[Path],
    *,
    lab: str | None = None,
    out: Path = Path("grades"),
    jobs: int = 1,
    timeout: float | None = None,
    progress: bool = True,
    roster: Path | None = None,
    overrides: Path | None = None,
    exports: Sequence[str] = (),
    assignment: str | None = None,
    due: str | None = None,
    late_penalty: float = 0.0,
    late_cap: float = 100.0,
    submitted_times: Path | None = None,
    shard: str | None = None,
) -> int:
    """Grade notebooks into ``out`` (gradebook.csv, gradebook.json, feedback/) and print a summary.

    ``shard`` (``"K/N"``) grades only the K-th of N slices of ``submissions``
    (:mod:`~robolab.grading.course.shards`) and writes ``out/shard.json`` for ``robolab merge``.

    Exit 0 whenever grading ran, whatever the scores; 2 when it could not
    (a user error, unknown lab, pytest missing, hidden tests that do not run);
    130 when interrupted (what finished is saved; the same command resumes).
    """
    from robolab.grading.running.runner import DEFAULT_TIMEOUT

    timeout = DEFAULT_TIMEOUT if timeout is None else timeout
    if importlib.util.find_spec("pytest") is None:
        return _error("pytest is not installed in this environment; it runs the hidden tests")
    if not submissions:
        return _error("no submissions given")
    if not timeout > 0 or timeout == float("inf"):
        return _error(f"--timeout must be a positive number of seconds, got {timeout:g}")
    if jobs < 1:
        return _error(f"--jobs must be at least 1, got {jobs}")
    # Only a path that names nothing stops the batch (a typo); a folder, a fifo or an
    # unreadable file is that submission's problem, reported in its row.
    missing = [p for p in submissions if not os.path.lexists(p)]
    if missing:
        return _error(f"no such notebook: {_shown(missing[0])}")
    from robolab.grading.running import stopping

    course = (roster, overrides, exports, assignment, due, late_penalty, late_cap, submitted_times)

    # From here SIGINT and SIGTERM only ask the batch to stop (it looks between waits);
    # the grading ends with exit 130 and a valid partial gradebook, within a few seconds.
    with stopping.on_signals():
        return _grade(submissions, lab, out, jobs, timeout, progress, shard, course)


def _grade(submissions, lab, out, jobs, timeout, progress, shard, course_options) -> int:
    """:func:`grade` once its arguments are checked, under the stop handlers."""
    from robolab.grading.labs import project_root
    from robolab.grading.running.runner import BatchInterrupted, grade_all, start_zygotes

    roster, overrides, exports, assignment, due, late_penalty, late_cap, submitted_times = (
        course_options
    )
    root = project_root()
    start_zygotes(root)  # first: their imports run while the batch is read and planned
    from robolab.grading.course.batch import BatchState, prepare_out
    from robolab.grading.course.outputs import Course

    try:
        if shard is not None:
            from robolab.grading.course.shards import parse_shard

            shard = parse_shard(shard)
        if lab is not None:
            find_lab(lab)
        inputs = _course_inputs(
            roster, overrides, due, late_penalty, late_cap, submitted_times, exports
        )
        out = prepare_out(out)
        state = BatchState.load(out)
        course = Course(out, state, *inputs, exports=exports, assignment=assignment)
        if inputs[1] is not None:
            course.keep_overrides(Path(overrides))
    except (LabError, ValueError) as exc:
        return _error(str(exc))
    planned = state.plan(list(submissions), lab, root, timeout)
    if shard is not None:
        planned = _slice(planned, shard, out)
    todo = [item for item in planned if item.previous is None]
    for item in planned:
        if item.previous is not None:
            state.record(item, item.previous)
    course.publish()

    def finished(index: int, result) -> None:
        result.flags = list(todo[index].flags)
        state.record(todo[index], result)
        course.publish(result)

    try:
        grade_all(
            [item.path for item in todo],
            labs=[item.lab for item in todo],
            names=[item.name for item in todo],
            root=root,
            jobs=jobs,
            timeout=timeout,
            progress=progress,
            on_result=finished,
        )
    except BatchInterrupted as exc:
        course.publish(final=True, report=False)
        print(
            f"robolab: interrupted: {exc.done} of {exc.total} submission(s) graded this run; "
            f"every finished one is saved in {_shown(out)}/ (gradebook.csv is valid). "
            "Run the same command again to grade the rest: finished submissions are not "
            "regraded.",
            file=sys.stderr,
        )
        return 130
    written = course.publish(final=True)
    names = {item.name for item in planned}
    this_run = [r for r in state.results() if r.name in names]
    print(course.summary(this_run))
    _print_outputs(out, written)
    reused = len(planned) - len(todo)
    if reused:
        print(f"{reused} unchanged submission(s) kept from the last run (not regraded)")
    fatal = [r for r in this_run if r.fatal]
    for r in fatal:
        print(
            f"robolab: grading could not run for {_shown(r.path)}: {'; '.join(r.errors)}",
            file=sys.stderr,
        )
    return FAILED if fatal else 0


def _print_outputs(out: Path, written: dict[str, Path]) -> None:
    print(
        f"\ngradebook: {_shown(out / 'gradebook.csv')} and {_shown(out / 'gradebook.json')}; "
        f"feedback: {_shown(out / 'feedback')}/"
        + "".join(f"; {kind}: {_shown(path)}" for kind, path in written.items())
    )


def merge(shards: Sequence[Path], *, out: Path, **course) -> int:
    """Merge the output folders of ``robolab grade --shard K/N`` into ``out``.

    ``out`` gets what one unsharded ``robolab grade`` of the same files with the same
    course options writes (gradebook, feedback, exports, class report); see
    :mod:`~robolab.grading.course.merge`. ``course`` takes :func:`grade`'s course
    options (``roster``, ``overrides``, ``exports``, ``assignment``, ``due``,
    ``late_penalty``, ``late_cap``, ``submitted_times``). Exit 0, or 2 when the shards
    cannot be merged.
    """
    from robolab.grading.course.batch import BatchError, prepare_out
    from robolab.grading.course.merge import merged_state, read_shards
    from robolab.grading.course.outputs import Course

    unknown = set(course) - set(_COURSE_DEFAULTS)
    if unknown:
        raise TypeError(f"merge() got unexpected course options {sorted(unknown)}")
    c = {**_COURSE_DEFAULTS, **course}
    overrides, exports, assignment = c["overrides"], c["exports"], c["assignment"]
    try:
        inputs = _course_inputs(
            c["roster"],
            overrides,
            c["due"],
            c["late_penalty"],
            c["late_cap"],
            c["submitted_times"],
            exports,
        )
        parts = read_shards(shards)
        state, modified = merged_state(parts, out)
        out = prepare_out(out)
        course = Course(
            out, state, *inputs, exports=exports, assignment=assignment, modified=modified
        )
        if inputs[1] is not None:
            course.keep_overrides(Path(overrides))
    except (BatchError, ValueError) as exc:
        return _error(str(exc))
    written = course.publish(final=True)
    results = state.results()
    print(f"merged {len(parts)} shard(s): {len(results)} submission(s)")
    print(course.summary(results))
    _print_outputs(out, written)
    return 0


def similarity(notebooks: Sequence[Path], *, out: Path, shown: int = 25) -> int:
    """Compare the submissions' exercise code (``robolab similarity``); see
    :mod:`~robolab.grading.course.similarity`. Never runs a notebook."""
    if importlib.util.find_spec("copydetect") is None:
        return _error(
            "robolab similarity needs copydetect: pip install 'robolab[instructor]' "
            "(or pip install copydetect)"
        )
    missing = [p for p in notebooks if not Path(p).is_file()]
    if missing:
        return _error(f"no such notebook: {_shown(missing[0])}")
    if len(notebooks) < 2:
        return _error("give at least two notebooks to compare")
    try:
        _output_folder(out, "--out")
    except ValueError as exc:
        return _error(str(exc))
    from robolab.grading.course.similarity import similarity_report

    pairs = similarity_report([Path(p) for p in notebooks], Path(out), shown=shown)
    close = [p for p in pairs if p.score >= 0.8]
    print(
        f"{len(pairs)} pair(s) of exercise code compared; {len(close)} at least 0.8 similar"
        + "".join(f"\n  {p.score:.2f}  {p.exercise}: {p.a} ~ {p.b}" for p in close[:10])
    )
    print(
        f"similarity: {_shown(Path(out) / 'similarity.csv')} and "
        f"{_shown(Path(out) / 'similarity.html')}"
    )
    return 0


def _slice(planned, shard, out: Path):
    """The submissions of ``shard`` among ``planned`` (the whole batch); writes its manifest."""
    from robolab.grading.course.batch import relative_paths
    from robolab.grading.course.shards import batch_identity, deal, write_manifest

    relative = relative_paths([item.key for item in planned])
    dealt = deal(relative, [item.lab for item in planned], shard.count)
    mine = [i for i, k in enumerate(dealt) if k == shard.index - 1]
    identity = batch_identity(relative, [item.digest for item in planned])
    members = [(planned[i].name, relative[i], planned[i].path) for i in mine]
    write_manifest(out, shard, identity, len(planned), members)
    return [planned[i] for i in mine]


def _shown(path) -> str:
    from robolab.grading.course.batch import display_path

    return display_path(path)


def check(notebook: Path) -> int:
    """Run the visible checks of the notebook's lab on the student's own functions.

    The notebook is loaded exactly as ``robolab grade`` loads it (the same
    cells, run whole and in order, with the same load limit per cell), but in
    this process: on a student's machine it is the student's own code, so no
    isolation is needed (grading isolates, checking does not). Exit 0 when
    every visible check passed, 1 when one failed, 2 when the notebook cannot
    be checked.
    """
    from robolab.grading.loading.notebook import load_notebook

    try:
        loaded = load_notebook(Path(notebook))
    except Exception as exc:  # any reading problem is the student's to fix: say it plainly
        return _error(f"cannot read {notebook}: {exc}")
    if not loaded.lab:
        return _error(f"{notebook} does not say which lab it is (no robolab.lab in its metadata)")
    try:
        checks = importlib.import_module(f"robolab.checks.{loaded.lab}")
    except (ModuleNotFoundError, ValueError):
        checks = None
    visible = (
        []
        if checks is None
        else sorted(
            (
                f
                for name, f in inspect.getmembers(checks, inspect.isfunction)
                if name.startswith("check_") and f.__module__ == checks.__name__
            ),
            key=lambda f: inspect.getsourcelines(f)[1],
        )
    )
    if not visible:
        return _error(
            f"{_shown(notebook)} is of lab {loaded.lab!r}, which has no visible checks "
            "(is the lab name in the notebook's metadata right?)"
        )
    # The same cells, run the same way, as `robolab grade` runs them in its worker: as
    # `__main__`, in a scratch folder of their own (here a temporary one).
    import tempfile

    from robolab.grading.loading.kernel import Notebook, load_budget
    from robolab.grading.running.limits import Limits

    budget = load_budget(Limits().wall_seconds, Limits().cpu_seconds)
    with (
        _numpy_kernels(),
        tempfile.TemporaryDirectory(prefix="robolab-check-") as folder,
        Notebook(folder) as kernel_notebook,
    ):
        problems = list(loaded.problems)
        ran = kernel_notebook.run(loaded.cells, *budget)
        problems += [loaded.problem(*failed) for failed in ran]
        failures = _run_checks(visible, kernel_notebook.namespace, problems)
    if failures:
        print(f"{failures} of {len(visible)} visible checks failed.")
        return 1
    print("visible checks passed (the graded tests are stronger: test your edge cases too).")
    return 0


@contextlib.contextmanager
def _numpy_kernels():
    """While checking, the library's numpy paths, not its numba kernels (unless chosen).

    The visible checks are small work (a few poses, a few dozen beams), which numpy does
    in milliseconds, while numba's first call imports numba (about a second) and compiles
    its kernels into the user's cache (tens of seconds on a busy laptop): a student's
    first ``robolab check`` would wait for compilation it does not need. The results are
    the same (:mod:`robolab.raycast`'s backends agree). ``ROBOLAB_RAYCAST`` set by the
    user is kept; when this sets it, it is removed afterwards, and the backend choice
    made under it is forgotten (in-process callers get numba back).
    """
    if "ROBOLAB_RAYCAST" in os.environ:
        yield
        return
    os.environ["ROBOLAB_RAYCAST"] = "numpy"
    try:
        yield
    finally:
        os.environ.pop("ROBOLAB_RAYCAST", None)
        raycast = sys.modules.get("robolab.raycast")
        if raycast is not None and getattr(raycast, "_JIT", False) is None:
            raycast._JIT = False  # chosen under the override: choose again on next use


def _run_checks(visible: list, namespace: dict, problems: list) -> int:
    """Print the load problems, run each visible check on its function; count the failures."""
    from robolab.checks.base import CheckFailed

    for p in sorted(problems, key=lambda p: p.cell_index):
        print(f"note: {p}")
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
    return failures


def _output_file(path: Path, what: str) -> Path:
    """Check that ``path`` can be written as a file (its folder is created); return it."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{what} {_shown(path)} is a folder; give a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(
            f"{what} {_shown(path)}: cannot create its folder ({exc.strerror})"
        ) from None
    if not os.access(path.parent, os.W_OK | os.X_OK) or (
        path.exists() and not os.access(path, os.W_OK)
    ):
        raise ValueError(f"{what} {_shown(path)} cannot be written (permission denied)")
    return path


def _output_folder(path: Path, what: str) -> Path:
    """Check that ``path`` is or can be made a writable folder; return it."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {_shown(path)} exists and is not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{what} {_shown(path)} cannot be created ({exc.strerror})") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise ValueError(f"{what} {_shown(path)} cannot be written (permission denied)")
    return path


def _is_stub_notebook(path: Path) -> bool:
    """Whether ``path`` is a notebook whose exercise cells hold stubs (never overwrite it)."""
    import ast

    import nbformat

    from robolab.grading.exports.release import is_stub
    from robolab.grading.labs import exercise_cells

    try:
        nb = nbformat.read(str(path), as_version=4)
        cells = exercise_cells(nb)
    except Exception:  # not a readable notebook: not a stub either
        return False
    return any(is_stub(f) for _, funcs in cells for f in funcs if isinstance(f, ast.FunctionDef))


def solve(notebooks: Sequence[Path], *, out: Path) -> int:
    """Write solved copies of the notebooks (or of every notebook in given folders) to ``out``.

    ``out`` ending in ``.ipynb`` is a file: one notebook is solved into it. Nothing is
    written over an input, over a stub notebook, or into the project's ``notebooks/``.
    """
    out = Path(out)
    try:  # the output first: it is cheap to check, nbformat is not cheap to import
        if out.suffix == ".ipynb":
            _output_file(out, "-o")
        else:
            _output_folder(out, "-o")
    except ValueError as exc:
        return _error(str(exc))
    import nbformat

    from robolab.grading.course.batch import atomic_write
    from robolab.grading.exports.solve import SolveError, _notebooks, solve_notebook, solve_paths
    from robolab.grading.labs import Lab, lab_of_notebook, project_root

    try:
        inputs = _notebooks([Path(p) for p in notebooks])
        if not inputs:
            raise SolveError("no notebooks found in " + ", ".join(_shown(p) for p in notebooks))
        single = out.suffix == ".ipynb"
        targets = [out] if single else [out / p.name for p in inputs]
        if single and len(inputs) != 1:
            raise SolveError(f"-o {_shown(out)} is one file but {len(inputs)} notebooks were given")
        stubs = (project_root() / "notebooks").resolve()
        for source, target in zip(inputs, targets, strict=True):
            if target.exists() and target.resolve() == source.resolve():
                raise SolveError(f"refusing to write the solution over its input {_shown(source)}")
            if target.resolve().parent == stubs or (target.is_file() and _is_stub_notebook(target)):
                raise SolveError(f"refusing to write over the stub notebook {_shown(target)}")
        if single:
            lab = lab_of_notebook(inputs[0])
            if lab is None:
                raise SolveError(f"{_shown(inputs[0])}: no robolab.lab in the notebook's metadata")
            nb = nbformat.read(str(inputs[0]), as_version=4)
            atomic_write(out, nbformat.writes(solve_notebook(nb, Lab(lab, project_root()))) + "\n")
            written = [out]
        else:
            written = solve_paths(inputs, out)
    except (SolveError, LabError, ValueError) as exc:
        return _error(str(exc))
    print(f"solved {len(written)} notebook(s) into {_shown(out)}")
    return 0


def release(out: Path, *, wheel: bool = True) -> int:
    """Build the student edition into ``out`` (and its wheel into ``out/dist``)."""
    try:
        _output_folder(out, "release folder")
    except ValueError as exc:
        return _error(str(exc))
    from robolab.grading.exports.release import ReleaseError, build_release

    try:
        build_release(out, wheel=wheel)
    except (ReleaseError, SyntaxError, ValueError) as exc:
        return _error(str(exc))
    print(f"student edition written to {_shown(out)}/ (no solutions, no hidden tests)")
    if wheel:
        print(f"installable wheel: {_shown(next((Path(out) / 'dist').glob('robolab-*.whl')))}")
    return 0


def gradescope(
    lab: str,
    *,
    out: Path,
    visibility: dict[str, str] | None = None,
    default_visibility: str = "visible",
    late_penalty: float = 0.0,
    late_cap: float = 100.0,
) -> int:
    """Build the Gradescope autograder zip for ``lab``."""
    from robolab.grading.exports.gradescope import BundleOptions, build_bundle

    try:
        _output_file(out, "-o")
        options = BundleOptions(
            visibility=dict(visibility or {}),
            default_visibility=default_visibility,
            late_penalty=late_penalty,
            late_cap=late_cap,
        )
        build_bundle(lab, out, options=options)
    except (LabError, ValueError) as exc:
        return _error(str(exc))
    print(f"Gradescope autograder for lab {lab!r}: {_shown(out)}")
    return 0


def data(out: Path | None, only: Sequence[str] | None) -> int:
    """Regenerate the bundled data (``robolab data``)."""
    try:
        if out is not None:
            _output_folder(out, "--out")
    except ValueError as exc:
        return _error(str(exc))
    from robolab.sim import make_data

    try:
        make_data(out_dir=out, only=only)
    except ValueError as exc:
        return _error(str(exc))
    return 0
