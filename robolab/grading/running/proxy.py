"""Call a student's notebook functions in an isolated worker process.

:func:`open_submission` loads a notebook's definitions into a fresh worker
(:mod:`robolab.grading.isolation.worker`) and returns a :class:`SubmissionProxy`, a
module-like object whose attributes call the student's functions there::

    lab = open_submission("alice.ipynb", lab="demo")
    lab.normalize([1.0, 3.0])        # runs in the worker, returns array([0.25, 0.75])
    lab.close()

The grader process -- which holds the hidden tests and the reference
solutions -- never runs student code. Arguments cross pickled; results come
back through :func:`robolab.grading.wire.codec.loads`, which accepts plain data
only. Every limit is enforced from this side: wall time per call (poll, then
kill), CPU time per call (read from ``/proc``), output size (a bounded buffer
drained by a thread). A call that crashes, hangs or exits the worker raises
:class:`WorkerCrashed` or :class:`WorkerTimeout`, and the next call gets a
fresh worker with the notebook's definitions reloaded.
"""

from __future__ import annotations

import pickle
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robolab.grading.isolation import sandbox
from robolab.grading.loading.kernel import load_budget
from robolab.grading.loading.notebook import CellProblem, LoadedNotebook, load_notebook
from robolab.grading.running.channel import Output, Worker
from robolab.grading.running.errors import (
    IsolationWarning,
    MissingFunction,
    ScratchExceeded,
    StudentCodeError,
    WorkerCrashed,
    WorkerStartError,
    WorkerTimeout,
    student_error_class,
)
from robolab.grading.running.limits import Limits, reference_limits
from robolab.grading.wire import codec, observe

if TYPE_CHECKING:
    from robolab.grading.running.answers import Answers

__all__ = [
    "reference_limits",
    "IsolationWarning",
    "Limits",
    "MissingFunction",
    "StudentCodeError",
    "SubmissionProxy",
    "WorkerCrashed",
    "WorkerStartError",
    "WorkerTimeout",
    "open_submission",
]

# --- the proxy ---------------------------------------------------------------------------------


class SubmissionProxy:
    """A module-like view of a student's notebook whose functions run in a worker.

    Attributes
    ----------
    lab : str or None
        The lab being graded.
    path : Path
        The notebook.
    functions : list of str
        Callables the notebook defines (after loading it in the worker).
    problems : list of CellProblem
        Cells that did not parse, or raised while being defined.
    sandbox : SandboxReport
        The isolation the worker applied.
    answers : Answers or None
        Answers the exercises below the one being graded with the reference
        (:mod:`robolab.grading.running.answers`); None: every call runs the student's code only.
    """

    def __init__(
        self,
        notebook: LoadedNotebook,
        lab: str | None,
        limits: Limits,
        answers: Answers | None = None,
    ) -> None:
        self.lab = lab
        self.answers = answers
        self.path = notebook.path
        # The parsed names until the worker reports what actually got defined.
        self.functions: list[str] = list(notebook.functions)
        self.problems: list[CellProblem] = list(notebook.problems)
        self.sandbox: sandbox.SandboxReport | None = None
        self._notebook = notebook
        self._limits = limits
        self._output = Output(limits.max_output_bytes)
        self._worker: Worker | None = None
        self._broken: StudentCodeError | None = None
        self._call_id = 0
        self._closed = False
        self._loaded = False
        self._timed_out: set[str] = set()
        #: Exercises whose reference answered a depcall in the current worker.
        self._disclosed: set[str] = set()
        #: Wall seconds the grader spent answering depcalls (not the submission's time).
        self.answering_seconds = 0.0
        #: Wall seconds (net of waiting for a CPU) of every load and call so far, against
        #: ``limits.budget_seconds``.
        self.spent_seconds = 0.0
        #: CPU seconds of every load and call so far (children included), against
        #: ``limits.cpu_budget_seconds``.
        self.spent_cpu_seconds = 0.0
        #: The longest CPU time of one call so far.
        self.longest_call_cpu_seconds = 0.0
        #: ``{what was cut short and by which limit: how many times}``.
        self._cut: dict[str, int] = {}

    def limits_hit(self) -> list[str]:
        """What a limit cut short, one line each, in the order it first happened."""
        return [f"{text} ({n} times)" if n > 1 else text for text, n in self._cut.items()]

    def usage(self) -> dict:
        """The submission's time so far and the limits that cut it short (for the report)."""
        return {
            "cpu_seconds": round(self.spent_cpu_seconds, 3),
            "awake_seconds": round(self.spent_seconds, 3),
            "longest_call_cpu_seconds": round(self.longest_call_cpu_seconds, 3),
            "cpu_budget_seconds": self._limits.cpu_budget_seconds,
            "wall_budget_seconds": self._limits.budget_seconds,
            "limits": self.limits_hit(),
        }

    def _note_cut(self, text: str) -> None:
        self._cut[text] = self._cut.get(text, 0) + 1

    def _left(self) -> tuple[float, float]:
        """CPU and wall seconds left in the submission's budgets."""
        return (
            self._limits.cpu_budget_seconds - self.spent_cpu_seconds,
            self._limits.budget_seconds - self.spent_seconds,
        )

    def _charge(self, worker: Worker) -> float:
        """Add the request that just ended to the submission's totals; return its CPU time."""
        self.spent_cpu_seconds += worker.request_cpu
        self.spent_seconds += worker.request_awake
        return worker.request_cpu

    def _budget_spent(self) -> str | None:
        """Which total budget is used up, in words; None while both last."""
        cpu_left, wall_left = self._left()
        if cpu_left <= 0:
            return f"total CPU time budget of {self._limits.cpu_budget_seconds:g} s"
        if wall_left <= 0:
            return f"total time budget of {self._limits.budget_seconds:g} s"
        return None

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name.startswith("_"):
            raise AttributeError(name)
        answers = self.__dict__.get("answers")
        reference = answers.direct(name) if answers is not None else None
        if reference is not None:
            # A test's own call of an exercise below the one it grades: the reference's
            # answer, so the student's version of it cannot move this exercise's points.
            return reference
        if name not in self.__dict__.get("functions", ()):
            raise MissingFunction(f"the notebook does not define {name}()", kind="missing")

        def call(*args: Any, **kwargs: Any) -> Any:
            return self._call(name, args, kwargs)

        call.__name__ = call.__qualname__ = name
        return call

    def __dir__(self) -> list[str]:
        return sorted(set(super().__dir__()) | set(self.functions))

    def __repr__(self) -> str:
        return f"<SubmissionProxy {self.path} lab={self.lab!r} functions={self.functions}>"

    def output(self) -> str:
        """What the student's code printed (stdout and stderr), truncated to the output limit."""
        return self._output.text()

    def close(self) -> None:
        """Kill the worker and everything it started, and remove its files."""
        self._closed = True
        if self._worker is not None:
            self._worker.close()
            self._worker = None

    def __enter__(self) -> SubmissionProxy:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- internals --

    def _start(self) -> Worker:
        """A fresh worker with the notebook's definitions loaded."""
        worker = Worker(self._limits, self._output)
        try:
            message = worker.receive(None)
            if message[0] != "ready":
                raise WorkerStartError(f"the grading worker could not isolate itself: {message[1]}")
            worker.report = sandbox.SandboxReport.from_dict(message[1])
        except (
            StudentCodeError,
            codec.CodecError,
            TypeError,
            IndexError,
        ) as exc:  # no student code has run yet
            worker.close()
            raise WorkerStartError(
                f"the grading worker did not start: {exc}\n{self._output.text()}"
            ) from exc
        except BaseException:
            worker.close()
            raise
        if self.sandbox is None:
            self.sandbox = worker.report
            _warn_if_weak(worker.report)
        # Loading (and every reload after a crash) is charged to the submission's budgets.
        cpu_left, wall_left = self._left()
        wall = max(min(self._limits.wall_seconds, wall_left), 0.0)
        cpu = max(min(self._limits.cpu_seconds, cpu_left), 0.0)
        try:
            budget = load_budget(wall, cpu)
            worker.send(("define", self._notebook.cells, *budget), wall)
            try:
                reply = worker.receive(cpu, alarm_after=budget[0])
            finally:
                self._charge(worker)
            message = self._expect(worker, reply, "defined")
        except (StudentCodeError, codec.CodecError, BrokenPipeError) as exc:
            if not isinstance(exc, StudentCodeError):
                exc = StudentCodeError(f"the worker broke the protocol: {exc}", kind="protocol")
            if isinstance(exc, WorkerTimeout):
                spent = self._budget_spent()
                if spent is not None:
                    exc = WorkerTimeout(f"the submission used up its {spent}", kind="timeout")
                self._note_cut(f"loading the notebook: {exc.message}")
            worker.close()
            self._broken = type(exc)(
                f"loading the notebook's definitions failed: {exc.message}",
                kind=exc.kind,
                student_traceback=exc.student_traceback,
            )
            if not self._loaded:
                self.problems.append(
                    CellProblem(-1, "error", self._broken.message, "loading the notebook")
                )
            raise self._broken from None
        if not self._loaded:
            self._loaded = True
            self.functions = [str(n) for n in message[1] if isinstance(n, str)]
            for problem in message[2]:
                index, kind, text = problem
                self.problems.append(self._notebook.problem(int(index), str(kind), str(text)))
                if kind == "timeout":
                    self._note_cut(f"loading the notebook: {self.problems[-1]}")
        limits = self._limits
        if any(p[1] == "timeout" for p in message[2]) and (
            wall < limits.wall_seconds or cpu < limits.cpu_seconds
        ):
            # What was left of a budget did not load the notebook (again): it is as good as
            # spent, rather than paid again, a little less each time, by every later call.
            worker.close()
            if wall < limits.wall_seconds:
                self.spent_seconds = max(self.spent_seconds, limits.budget_seconds)
            if cpu < limits.cpu_seconds:
                self.spent_cpu_seconds = max(self.spent_cpu_seconds, limits.cpu_budget_seconds)
            spent = self._budget_spent()
            self._note_cut(f"loading the notebook: the submission used up its {spent}")
            raise WorkerTimeout(
                f"loading the notebook was stopped: the submission used up its {spent}",
                kind="timeout",
            )
        return worker

    def _expect(self, worker: Worker, message: Any, kind: str, call_id: int | None = None) -> Any:
        ok = isinstance(message, tuple) and message and message[0] == kind
        if ok and call_id is not None:
            ok = len(message) in ((3, 4) if kind in ("ok", "error") else (3,))
            ok = ok and message[1] == call_id
        if kind == "defined":
            ok = (
                ok
                and len(message) == 3
                and isinstance(message[1], list)
                and isinstance(message[2], list)
            )
        if not ok:
            worker.close()
            raise StudentCodeError(
                f"the worker answered out of turn ({_short(message)})", kind="protocol"
            )
        return message

    def _call(self, name: str, args: tuple, kwargs: dict) -> Any:
        if self._closed:
            raise RuntimeError(f"the submission {self.path} is closed")
        if self._broken is not None:
            raise type(self._broken)(
                self._broken.message,
                kind=self._broken.kind,
                student_traceback=self._broken.student_traceback,
            )
        try:
            _picklable((args, kwargs))
        except Exception as exc:
            raise TypeError(f"arguments to {name}() cannot be sent to the worker: {exc}") from exc
        spent = self._budget_spent()
        if spent is not None:
            self._note_cut(f"calls not run: the submission used up its {spent}")
            raise WorkerTimeout(
                f"{name}() was not run: the submission used up its {spent}", kind="timeout"
            )
        worker = self._worker
        if (
            worker is not None
            and worker.cpu_seconds()
            > worker.plan.cpu_lifetime_seconds - self._limits.cpu_seconds - 1
        ):
            self._discard()  # restart before the lifetime CPU limit could cut a fair call short
            worker = None
        if (
            worker is not None
            and self.answers is not None
            and self.answers.exercise in self._disclosed
        ):
            # This worker was given the reference's answers of the exercise now graded (it
            # was below one graded earlier): a fresh worker, so nothing it kept can answer.
            self._discard()
            worker = None
        if worker is None:
            worker = self._worker = self._start()
            if (spent := self._budget_spent()) is not None:  # the load used up the rest
                self._note_cut(f"calls not run: the submission used up its {spent}")
                raise WorkerTimeout(
                    f"{name}() was not run: the submission used up its {spent}", kind="timeout"
                )
        self._call_id += 1
        call_id = self._call_id
        wall, cpu = self._limits.wall_seconds, self._limits.cpu_seconds
        if name in self._timed_out:
            # It ran out of time before: it most likely will again, and each try
            # would cost a full wall limit. A small input still gets its answer.
            wall, cpu = min(wall, max(1.0, wall / 10)), min(cpu, max(1.0, cpu / 10))
        cpu_left, wall_left = self._left()
        wall, cpu = min(wall, wall_left), min(cpu, cpu_left)
        answering = self.answering_seconds
        below = self.answers.stubbed(name) if self.answers is not None else ()
        try:
            try:
                worker.send(("call", call_id, name, args, kwargs, cpu, below), wall)
                message = worker.receive(cpu, on_depcall=self._depcalls(call_id, below))
            finally:
                # The grader's own time answering depcalls counts for the call's wall limit
                # (a bound), not for the submission's total budget: it is not the student's.
                answered = self.answering_seconds - answering
                worker.request_awake = max(0.0, worker.request_awake - answered)
                call_cpu = self._charge(worker)
                self.longest_call_cpu_seconds = max(self.longest_call_cpu_seconds, call_cpu)
        except codec.CodecError as exc:
            self._discard()
            raise StudentCodeError(
                f"{name}() returned a value the grader does not accept: {exc}", kind="result"
            ) from None
        except (StudentCodeError, BrokenPipeError) as exc:
            self._discard()
            if isinstance(exc, WorkerTimeout):
                self._timed_out.add(name)
                spent = self._budget_spent()
                if spent is not None:
                    exc = WorkerTimeout(
                        f"timed out: the submission used up its {spent}", kind="timeout"
                    )
            if isinstance(exc, (WorkerTimeout, ScratchExceeded)):
                self._note_cut(f"{name}(): {exc.message}")
            if isinstance(exc, BrokenPipeError):
                raise WorkerCrashed(
                    f"the worker died before {name}() could run", kind="crash"
                ) from None
            raise type(exc)(
                f"{name}(): {exc.message}", kind=exc.kind, student_traceback=exc.student_traceback
            ) from None
        return self._answer(worker, name, call_id, message, args, kwargs)

    def _depcalls(self, call_id: int, below: tuple[str, ...]) -> Callable[[Any], tuple] | None:
        """The handler of the running call's depcalls: the reference's answers (see answers.py)."""
        if not below or self.answers is None:
            return None
        answers = self.answers

        def answer(message: tuple) -> tuple:
            started = time.monotonic()
            try:
                return checked(message)
            finally:
                self.answering_seconds += time.monotonic() - started

        def checked(message: tuple) -> tuple:
            if len(message) != 6 or message[1] != call_id or message[2] not in below:
                raise StudentCodeError(
                    f"the worker asked for an answer out of turn ({_short(message[:3])})",
                    kind="protocol",
                )
            reply = answers.answer(*message[2:])
            if reply[0] in ("answer", "raise"):
                self._disclosed.add(message[2])
            try:
                _picklable(reply)
            except Exception as exc:  # noqa: BLE001 - a reference value that cannot cross
                return ("own", f"the reference's answer cannot be sent: {exc}")
            return reply

        return answer

    def _answer(
        self,
        worker: Worker,
        name: str,
        call_id: int,
        message: Any,
        args: tuple = (),
        kwargs: dict | None = None,
    ) -> Any:
        head = message[0] if isinstance(message, tuple) and message else None
        if head == "ok":
            message = self._expect(worker, message, "ok", call_id)
            if len(message) < 4:
                return message[2]
            # What the call did to its arguments and how its result shares memory with
            # them, replayed on the caller's objects (robolab.grading.wire.observe).
            return observe.replay(message[2], message[3], args, kwargs or {})
        if head == "error":
            message = self._expect(worker, message, "error", call_id)
            info = message[2]
            if len(message) == 4:  # what it changed before raising
                observe.replay(None, message[3], args, kwargs or {})
            if not (isinstance(info, dict) and isinstance(info.get("bases"), list)):
                self._discard()
                raise StudentCodeError("the worker sent a malformed error", kind="protocol")
            cls = student_error_class([b for b in info["bases"] if isinstance(b, str)])
            if cls.__name__ == "StudentMemoryError":
                self._note_cut(
                    f"{name}(): ran out of memory (limit {self._limits.memory_bytes / 2**30:g} GiB)"
                )
            raise cls(
                str(info.get("message", "")),
                kind=str(info.get("type", "Exception")),
                student_traceback=str(info.get("traceback", "")),
            )
        if head == "missing":
            self._expect(worker, message, "missing", call_id)
            raise MissingFunction(f"the notebook does not define {name}()", kind="missing")
        if head == "exit":
            self._expect(worker, message, "exit", call_id)
            self._discard()  # the student asked to stop; start clean for the next call
            raise WorkerCrashed(
                f"{name}() exited the worker with {_short(message[2])}", kind="crash"
            )
        self._discard()
        raise StudentCodeError(
            f"the worker answered out of turn ({_short(message)})", kind="protocol"
        )

    def _discard(self) -> None:
        self._disclosed.clear()
        if self._worker is not None:
            self._worker.close()
            self._worker = None


def _picklable(value: Any) -> None:
    """Raise what pickling ``value`` raises; arrays are not copied (out of band, dropped):
    the message itself is pickled once, when it is sent (``Worker.reply``)."""
    pickle.dumps(value, protocol=5, buffer_callback=_drop)


def _drop(buffer: pickle.PickleBuffer) -> bool:
    return False


def _short(value: Any, limit: int = 200) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "..."


_warned: set[str] = set()


def _warn_if_weak(report: sandbox.SandboxReport) -> None:
    """Warn (once per process and problem) when the OS does not isolate the worker fully."""
    problems = []
    if not report.protects_answers:
        problems.append(
            "neither Landlock nor a mount namespace is available: submissions could read "
            "the reference solutions and hidden tests"
        )
    if report.network_denied == "no":
        problems.append("submissions can open network connections")
    if not report.process_limit:
        problems.append("the worker runs as root, so the process limit does not hold")
    if not report.protects_processes:
        problems.append("submissions can signal or reconfigure other processes of the grader")
    for problem in problems:
        if problem in _warned:
            continue
        _warned.add(problem)
        text = f"robolab grading: {problem} ({'; '.join(report.notes) or 'see docs/grading.md'})"
        warnings.warn(text, IsolationWarning, stacklevel=3)
        print(f"WARNING: {text}", file=sys.stderr)


def open_submission(
    path: str | Path,
    lab: str | None = None,
    *,
    limits: Limits | None = None,
    answers: Answers | None = None,
) -> SubmissionProxy:
    """Load a notebook into an isolated worker and return a proxy to its functions.

    Parameters
    ----------
    path : str or Path
        The student's ``.ipynb``.
    lab : str, optional
        The lab being graded: the cells its exercises need are loaded. Without
        it, the cells every function of the notebook needs are (the proxy's
        ``lab`` is then the notebook's metadata).
    limits : Limits, optional
        Resource limits of the worker (defaults: :class:`Limits`).
    answers : Answers, optional
        The reference's answers for the exercises below the one being graded
        (:mod:`robolab.grading.running.answers`; the pytest plugin passes them).

    Returns
    -------
    SubmissionProxy
        Open; call :meth:`SubmissionProxy.close` (or use ``with``) when done.

    Raises
    ------
    NotebookError
        When the file is not a readable notebook.
    WorkerStartError
        When the worker cannot be started or isolated.
    """
    # Graded as a lab, the lab's exercises are what the cells are chosen for; opened
    # without one, every function the notebook defines is.
    notebook = load_notebook(path, lab=lab) if lab else load_notebook(path, every_function=True)
    if lab is not None and notebook.lab is not None and lab != notebook.lab:
        warnings.warn(
            f"{notebook.path} says it is lab {notebook.lab!r}, graded as {lab!r}", stacklevel=2
        )
    proxy = SubmissionProxy(notebook, lab or notebook.lab, limits or Limits(), answers)
    try:
        proxy._worker = proxy._start()
    except StudentCodeError:
        pass  # recorded in proxy.problems; every call raises it again
    return proxy
