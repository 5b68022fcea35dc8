"""Grade submissions: one pytest subprocess per notebook, in parallel.

The grader process that runs pytest holds the hidden tests and the reference
solutions; the student's code runs behind the ``lab`` fixture in the isolated
worker (:mod:`robolab.grading.running.proxy`). This module only drives those pytest
runs and reads back the JSON report of :mod:`robolab.grading.running.pytest_plugin`.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robolab.grading.isolation import warm
from robolab.grading.labs import LabError, find_lab, lab_of_notebook, project_root
from robolab.grading.running import stopping
from robolab.grading.running.stopping import REAP, TICK, stop_run, stop_running

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = [
    "DEFAULT_TIMEOUT",
    "BatchInterrupted",
    "SubmissionResult",
    "TestOutcome",
    "grade_all",
    "grade_submission",
    "start_zygotes",
    "stop_running",
]

#: Seconds one submission may take in total before its pytest run is stopped, not counting
#: the time its pytest run and workers waited for a CPU (a backstop: a submission's own
#: time is bounded by its budgets, see docs/grading.md).
DEFAULT_TIMEOUT = 600.0
#: pytest's default plugins that do nothing unless their option is given (``--doctest-*``,
#: ``--junitxml``, ``--pastebin``, ``--setup-only``, ``--setup-plan``, ``--stepwise``),
#: turned off in grading runs.
_UNUSED_PLUGINS = ("doctest", "junitxml", "pastebin", "setuponly", "setupplan", "stepwise")
#: pytest exit codes that mean the hidden tests ran (0: all passed, 1: some failed).
_RAN = (0, 1)


@dataclass(frozen=True)
class TestOutcome:
    """One hidden test's result for one submission."""

    __test__ = False  # a result, not a pytest test class

    nodeid: str
    description: str
    exercise: str
    points: float
    outcome: str  # passed | failed | error | skipped | not run
    message: str = ""

    @property
    def passed(self) -> bool:
        return self.outcome == "passed"


@dataclass
class SubmissionResult:
    """Everything known about grading one submission.

    ``errors`` are problems with the submission or its run, shown to the
    student; ``fatal`` is set when grading itself could not run (no hidden
    tests, pytest broken), which is the instructor's problem.
    """

    path: Path
    name: str
    lab: str | None
    tests: list[TestOutcome] = field(default_factory=list)
    problems: list[dict] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    fatal: bool = False
    seconds: float = 0.0
    #: What the machine's sandbox failed to protect ("" when everything held), from
    #: :func:`robolab.grading.isolation.protection.batch_protection`.
    isolation: str = ""
    #: Things the instructor must look at (a lab that differs from the batch's, ...);
    #: shown in the summary and the gradebook, not a grading error.
    flags: list[str] = field(default_factory=list)
    #: What a time or memory limit cut short (flagged in the gradebook and the summary).
    limits: list[str] = field(default_factory=list)
    #: CPU seconds the submission's own processes used (loads and calls, children included).
    cpu_seconds: float = 0.0
    #: Wall seconds of its loads and calls, less the time its worker waited for a CPU.
    awake_seconds: float = 0.0

    def to_dict(self) -> dict:
        """A JSON-ready copy (the path as text, surrogate escapes kept) for the batch state."""
        data = asdict(self)
        data["path"] = os.fsdecode(self.path)
        return data

    @classmethod
    def from_dict(cls, data: dict) -> SubmissionResult:
        """Inverse of :meth:`to_dict`; keys this version does not know are ignored."""
        known = {f.name for f in fields(cls)}
        data = {k: v for k, v in data.items() if k in known}
        data["path"] = Path(data["path"])
        test_fields = {f.name for f in fields(TestOutcome)}
        data["tests"] = [
            TestOutcome(**{k: v for k, v in t.items() if k in test_fields})
            for t in data.get("tests", [])
        ]
        return cls(**data)

    def exercise_scores(self) -> dict[str, tuple[float, float]]:
        """``{exercise: (earned, possible)}`` in the order the tests run."""
        scores: dict[str, tuple[float, float]] = {}
        for t in self.tests:
            earned, possible = scores.get(t.exercise, (0.0, 0.0))
            scores[t.exercise] = (earned + (t.points if t.passed else 0.0), possible + t.points)
        return scores

    @property
    def total(self) -> float:
        return sum(t.points for t in self.tests if t.passed)

    @property
    def max_points(self) -> float:
        return sum(t.points for t in self.tests)


class BatchInterrupted(KeyboardInterrupt):
    """Grading was interrupted (Ctrl-C, SIGTERM); ``done`` results had finished before."""

    def __init__(self, done: int, total: int):
        super().__init__(f"interrupted after {done} of {total} submissions")
        self.done, self.total = done, total


def _pytest_command(
    python: str, root: Path, tests: Path, notebook: Path, report: Path
) -> list[str]:
    return [
        python,
        "-m",
        "pytest",
        str(tests),
        "--rootdir",
        str(root),
        "--notebook",
        str(notebook),
        "--grading-report",
        str(report),
        "-p",
        "robolab.grading.running.pytest_plugin",
        "-p",
        "no:cacheprovider",
        # Plugins that act only when their own option is given (none is): each registered
        # plugin costs every run its fixture scan (issue 29). Fixtures a test may use stay.
        *(arg for name in _UNUSED_PLUGINS for arg in ("-p", f"no:{name}")),
        "-q",
        "--tb=no",
        "--no-header",
    ]


def _pytest_env(workers: warm.Zygote | None) -> dict[str, str]:
    """The environment of a pytest run (and of the grader zygote that forks them)."""
    env = dict(
        os.environ,
        PYTEST_DISABLE_PLUGIN_AUTOLOAD="1",
        MPLBACKEND="Agg",
        PYTHONDONTWRITEBYTECODE="1",
    )
    if workers is not None:
        env[warm.FD_VARIABLE] = str(workers.fileno())
    return env


def start_zygotes(root: Path | None = None) -> None:
    """Start the worker zygote and the grader zygote of ``root`` now, side by side.

    Each imports its libraries (numpy and matplotlib; pytest) for about half a second:
    started together, before anything else of the batch, they do that on both cores while
    the grader reads the submissions, instead of one after the other when the first
    submission needs them. Nothing waits for them here; a request simply queues until its
    zygote is ready. A no-op when warm grading is off (``ROBOLAB_WARM_WORKERS=0``) or the
    zygotes already run.
    """
    workers = warm.shared()
    if workers is not None:
        warm.shared_grader(str((root or project_root()).resolve()), _pytest_env(workers))


def _run(cmd: list[str], cwd: Path, log: Path, timeout: float) -> tuple[int | None, float]:
    """Run ``cmd`` in its own session; on timeout SIGINT then SIGKILL its process group.

    The timeout counts on a clock that leaves out the time the run and its workers (whose
    pids the proxy appends to a file next to ``log``) waited for a CPU, so a busy machine
    never reaches it. Returns the exit code (None after a timeout) and the wall seconds.
    """
    from robolab.grading.isolation.processes import WORKER_PIDS_VARIABLE, AwakeClock

    workers = warm.shared()  # one warm worker zygote serves every pytest run of this process
    pids = log.with_name("workers.txt")
    env = dict(_pytest_env(workers), **{WORKER_PIDS_VARIABLE: str(pids)})
    start = time.monotonic()
    if stopping.runs_stopping():
        return None, 0.0
    # Not under a lock: starting a run may wait for the zygote, and stop_running must
    # not. A run that starts after a stop was asked for is stopped by the loop below.
    with log.open("wb") as out:
        proc = _launch(cmd, cwd, env, out.fileno(), workers)
    stopping.remember_run(proc)
    code: int | None = None
    clock = AwakeClock(proc.pid)
    try:
        while code is None and not stopping.runs_stopping():
            for pid in _pids_in(pids):
                clock.watch(pid)
            left = timeout - clock.elapsed()
            if left <= 0:
                break
            try:
                code = proc.wait(timeout=min(TICK, left))
            except subprocess.TimeoutExpired:
                pass
        if code is None:
            # Timed out or asked to stop: SIGINT first so pytest's finalizers close the
            # student's worker, then make sure.
            stop_run(proc)
    finally:
        stopping.forget_run(proc)
    return code, time.monotonic() - start


def _pids_in(path: Path) -> list[int]:
    """The worker pids a pytest run wrote down so far."""
    try:
        return [int(line) for line in path.read_text(encoding="ascii").split()]
    except (OSError, ValueError):
        return []


def _launch(cmd: list[str], cwd: Path, env: dict, out: int, workers: warm.Zygote | None) -> Any:
    """Fork the pytest run from the grader zygote (pytest and numpy imported), else start it.

    Either way it runs in its own session (killed as a process group), output to ``out``.
    """
    grader = None
    if workers is not None and cmd[:3] == [sys.executable, "-m", "pytest"]:
        grader = warm.shared_grader(str(cwd), env)
    if grader is not None:
        request = {"args": cmd[3:], "env": env, "cwd": str(cwd), "keep": [workers.fileno()]}
        try:
            return grader.spawn(request, (out,))
        except warm.ZygoteError as exc:
            if stopping.runs_stopping():  # its zygote is closing with the batch: start nothing
                raise
            print(f"robolab grade: starting pytest cold: {exc}", file=sys.stderr)
    return subprocess.Popen(
        cmd,
        cwd=cwd,
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=out,
        stderr=subprocess.STDOUT,
        start_new_session=True,
        pass_fds=() if workers is None else (workers.fileno(),),
    )


def _tail(path: Path, chars: int = 1500) -> str:
    try:
        return path.read_text(errors="replace")[-chars:].strip()
    except OSError:
        return ""


def grade_submission(
    path: Path,
    *,
    lab: str | None = None,
    name: str | None = None,
    root: Path | None = None,
    timeout: float = DEFAULT_TIMEOUT,
    python: str | None = None,
) -> SubmissionResult:
    """Run the hidden tests of the submission's lab on the notebook at ``path``.

    Never raises for a bad submission: what went wrong is in the result's
    ``errors`` (and ``fatal`` when the grader itself is at fault).
    """
    path = Path(path)
    result = SubmissionResult(path=path, name=name or path.stem, lab=lab)
    try:  # read here, safely, so that a file that is no notebook fails alone, graded as nothing
        declared = lab_of_notebook(path)
    except LabError as exc:
        result.errors.append(str(exc))
        return result
    if result.lab is None:
        result.lab = declared
        if result.lab is None:
            result.errors.append(
                "the notebook does not say which lab it is (no robolab.lab in its metadata) "
                "and no --lab was given"
            )
            return result
    try:
        spec = find_lab(result.lab, root)
    except LabError as exc:
        result.errors.append(str(exc))
        result.fatal = True
        return result

    with tempfile.TemporaryDirectory(prefix="robolab-grade-") as tmp:
        report_path, log = Path(tmp) / "report.json", Path(tmp) / "pytest.log"
        cmd = _pytest_command(
            python or sys.executable, spec.root, spec.hidden_tests, path.absolute(), report_path
        )
        code, result.seconds = _run(cmd, spec.root, log, timeout)
        report = json.loads(report_path.read_text()) if report_path.is_file() else None
        log_tail = _tail(log)

    if report is None:
        if code is None:
            result.limits.append(f"grading stopped at the batch's timeout of {timeout:g} s")
        result.fatal = code is not None
        result.errors.append(
            f"grading timed out after {timeout:g} s"
            if code is None
            else f"pytest could not run the hidden tests (exit {code}): {log_tail}"
        )
        return result
    result.problems = list(report.get("problems", []))
    usage = report.get("usage") or {}
    result.cpu_seconds = float(usage.get("cpu_seconds", 0.0))
    result.awake_seconds = float(usage.get("awake_seconds", 0.0))
    result.limits = [str(line) for line in usage.get("limits", [])]
    if report.get("collection_errors") or (code is not None and code not in _RAN):
        result.fatal = True
        result.errors.append(
            f"the hidden tests of lab {result.lab!r} could not run (pytest exit {code}); "
            "see the grader's log"
        )
        print(f"robolab grade: {path}: pytest exit {code}\n{log_tail}", file=sys.stderr)
        return result  # no score: the grader, not the submission, is at fault
    if code is None:
        result.errors.append(
            f"grading timed out after {timeout:g} s; tests that had not finished earn nothing"
        )
        result.limits.append(f"grading stopped at the batch's timeout of {timeout:g} s")
    result.tests = [
        TestOutcome(
            nodeid=t["nodeid"],
            description=t["description"],
            exercise=t["exercise"],
            points=float(t["points"]),
            outcome=t["outcome"],
            message=t.get("message", ""),
        )
        for t in report.get("tests", [])
    ]
    return result


def grade_all(
    paths: Sequence[Path],
    *,
    lab: str | None = None,
    labs: Sequence[str | None] | None = None,
    names: Sequence[str] | None = None,
    root: Path | None = None,
    jobs: int = 1,
    timeout: float = DEFAULT_TIMEOUT,
    progress: bool = True,
    on_result: Callable[[int, SubmissionResult], None] | None = None,
) -> list[SubmissionResult]:
    """Grade every submission, ``jobs`` at a time; results come back in the order of ``paths``.

    Parameters
    ----------
    lab, labs
        The lab for every submission, or one per submission (None: the notebook's own).
    names
        The submissions' names (default: their stems).
    on_result
        Called in this thread with ``(index, result)`` as soon as each submission finishes,
        so that the caller can write it down before the next one ends.

    Raises
    ------
    BatchInterrupted
        When a stop is requested (SIGINT or SIGTERM under
        :func:`~robolab.grading.running.stopping.on_signals`, looked at every
        :data:`~robolab.grading.running.stopping.TICK` seconds), or on a KeyboardInterrupt
        where no such handler is installed: every pytest run under way is stopped first
        (bounded); ``on_result`` has seen every result that finished and was published.
    """
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if not timeout > 0:
        raise ValueError(f"timeout must be a positive number of seconds, got {timeout}")
    root = root or project_root()
    paths = [Path(p) for p in paths]
    if stopping.requested():  # asked while the batch was being read: start nothing
        raise BatchInterrupted(0, len(paths))
    stopping.allow_runs()
    if paths:
        start_zygotes(root)
    from tqdm import tqdm  # here: importing it costs robolab grade 25 ms before its zygotes start

    from robolab.grading.isolation import protection as _protection  # probed once per batch

    # The probe (a real worker trying what a hostile one would) runs beside the grading, in
    # a thread of its own: it says what the gradebook's isolation column holds, and gates
    # nothing (each worker isolates itself as before). Results wait for it before anyone
    # sees them, and its line is printed before the first of them.
    probe = _in_daemon_thread(_protection.batch_protection, "robolab-probe")
    protection = None
    labs = list(labs) if labs is not None else [lab] * len(paths)
    names = list(names) if names is not None else [p.stem for p in paths]
    results: list[SubmissionResult | None] = [None] * len(paths)
    done = 0
    waiting: list[int] = []  # finished before the probe: published once it is known

    def publish(index: int, bar: tqdm) -> None:
        nonlocal done
        results[index].isolation = protection.column
        done += 1
        if on_result is not None:
            on_result(index, results[index])
        bar.update(1)

    tasks = [
        lambda p=p, la=la, n=n: grade_submission(p, lab=la, name=n, root=root, timeout=timeout)
        for p, la, n in zip(paths, labs, names, strict=True)
    ]
    futures, threads = _in_daemon_threads(tasks, jobs)
    index_of = {future: i for i, future in enumerate(futures)}
    pending: set[Future] = {probe, *futures}
    interrupted = False
    try:
        with tqdm(
            total=len(paths), unit="submission", disable=not progress, file=sys.stderr
        ) as bar:
            # Short waits, and a look at the stop request between them: a signal never
            # raises in here (see robolab.grading.running.stopping).
            while pending and not stopping.requested():
                finished, pending = wait(pending, timeout=TICK, return_when=FIRST_COMPLETED)
                for future in sorted(finished, key=lambda f: index_of.get(f, -1)):
                    if future is probe:
                        protection = probe.result()
                        bar.clear()
                        protection.announce()
                        bar.refresh()
                        for index in waiting:
                            publish(index, bar)
                        waiting.clear()
                        continue
                    index = index_of[future]
                    results[index] = future.result()
                    if protection is None:
                        waiting.append(index)
                    else:
                        publish(index, bar)
    except KeyboardInterrupt:  # no stop handler installed (grade_all called as a library)
        interrupted = True
    except BaseException:
        _halt(threads)
        raise
    if interrupted or pending - {probe} or (pending and stopping.requested()):
        # The probe is not waited for (a daemon thread): its worker dies with the zygote.
        _halt(threads)
        raise BatchInterrupted(done, len(paths)) from None
    return [r for r in results if r is not None]


def _in_daemon_threads(
    tasks: Sequence[Callable[[], SubmissionResult]], jobs: int
) -> tuple[list[Future], list[threading.Thread]]:
    """Run ``tasks`` in ``jobs`` daemon threads, in order; their futures and the threads.

    Daemon threads (not a :class:`~concurrent.futures.ThreadPoolExecutor`, whose threads
    the interpreter joins at exit): a stopped batch waits for them a bounded time only
    (:func:`_halt`). Once a stop is asked for, no thread takes another task.
    """
    futures = [Future() for _ in tasks]
    order = iter(range(len(tasks)))
    lock = threading.Lock()  # taken by these threads only, never by the main thread

    def work() -> None:
        while not stopping.runs_stopping():
            with lock:
                index = next(order, None)
            if index is None:
                return
            future = futures[index]
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(tasks[index]())
            except BaseException as exc:  # noqa: BLE001 - handed to the main thread
                future.set_exception(exc)

    threads = [
        threading.Thread(target=work, name=f"robolab-grade-{k}", daemon=True)
        for k in range(min(jobs, len(tasks)))
    ]
    for thread in threads:
        thread.start()
    return futures, threads


def _halt(threads: Sequence[threading.Thread]) -> None:
    """Stop the batch: no new run, every running one stopped, the threads given a bounded wait."""
    stop_running()
    deadline = time.monotonic() + REAP
    for thread in threads:
        thread.join(max(0.0, deadline - time.monotonic()))


def _in_daemon_thread(function: Callable[[], Any], name: str) -> Future:
    """``function()`` in a daemon thread: an interrupted batch exits without waiting for it."""
    future: Future = Future()

    def run() -> None:
        if not future.set_running_or_notify_cancel():
            return
        try:
            future.set_result(function())
        except BaseException as exc:  # noqa: BLE001 - handed to whoever waits for it
            future.set_exception(exc)

    threading.Thread(target=run, name=name, daemon=True).start()
    return future
