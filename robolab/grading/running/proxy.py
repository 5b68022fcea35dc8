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

import builtins
import os
import pickle
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import warnings
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import robolab
from robolab.grading.isolation import processes, sandbox
from robolab.grading.isolation.worker import HEADER
from robolab.grading.loading.kernel import load_budget
from robolab.grading.loading.notebook import CellProblem, LoadedNotebook, load_notebook
from robolab.grading.wire import codec, observe

__all__ = [
    "reference_budget",
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

#: Without ``Limits.total_wall_seconds``, a submission's calls may take this many per-call
#: wall limits in total.
BUDGET_CALLS = 5
#: A lab whose hidden tests state ``REFERENCE_SECONDS`` (the reference solution's call time)
#: gives a submission this many times that, at least :data:`MIN_BUDGET_SECONDS` (and never
#: more than :data:`BUDGET_CALLS` per-call limits): see :func:`reference_budget`.
BUDGET_FACTOR = 8.0
MIN_BUDGET_SECONDS = 60.0

#: The grader thread's CPU clock, which decoding a result is charged by.
decode_clock = time.thread_time

#: Largest message accepted from a worker (a result, in pickled form): the codec's limit.
MAX_MESSAGE_BYTES = codec.LIMITS.max_bytes
#: Seconds a worker may take to start and isolate itself (before student code runs).
STARTUP_SECONDS = 30.0
#: How often a waiting grader checks the worker's CPU time and liveness.
POLL_SECONDS = 0.05


# --- errors ------------------------------------------------------------------------------------


class StudentCodeError(Exception):
    """Raised by, or because of, student code.

    Attributes
    ----------
    kind : str
        The student's exception type name (``"ValueError"``), or ``"crash"``,
        ``"timeout"``, ``"missing"``, ``"result"`` (a result that is not plain
        data) or ``"protocol"`` (the worker broke the protocol).
    message : str
        What happened, in words that may be shown to the student.
    student_traceback : str
        The traceback from the worker (student code only), may be empty.
    """

    def __init__(self, message: str, *, kind: str = "error", student_traceback: str = "") -> None:
        super().__init__(message)
        self.kind = kind
        self.message = message
        self.student_traceback = student_traceback

    def __str__(self) -> str:
        return self.message


class WorkerCrashed(StudentCodeError):
    """The worker died: segfault, ``os._exit``, ``sys.exit``, memory limit, killed."""


class WorkerTimeout(StudentCodeError):
    """A call exceeded its wall-time or CPU-time limit."""


class MissingFunction(StudentCodeError, AttributeError):
    """The notebook does not define the function."""


class WorkerStartError(RuntimeError):
    """The worker could not be started or isolated: grading itself cannot run."""


class IsolationWarning(UserWarning):
    """The operating system does not isolate the worker as documented."""


# Builtin exceptions a student's exception is re-raised as (together with
# StudentCodeError), so that `pytest.raises(ValueError)` works across the boundary.
_REBUILT = (
    ArithmeticError,
    AssertionError,
    AttributeError,
    BufferError,
    EOFError,
    FloatingPointError,
    ImportError,
    IndexError,
    KeyError,
    LookupError,
    MemoryError,
    ModuleNotFoundError,
    NameError,
    NotImplementedError,
    OSError,
    BlockingIOError,
    ChildProcessError,
    ConnectionError,
    BrokenPipeError,
    ConnectionAbortedError,
    ConnectionRefusedError,
    ConnectionResetError,
    FileExistsError,
    FileNotFoundError,
    InterruptedError,
    IsADirectoryError,
    NotADirectoryError,
    PermissionError,
    ProcessLookupError,
    TimeoutError,
    OverflowError,
    RecursionError,
    ReferenceError,
    RuntimeError,
    SystemError,
    TypeError,
    UnboundLocalError,
    UnicodeError,
    ValueError,
    ZeroDivisionError,
)
_BUILTIN_BY_NAME = {cls.__name__: cls for cls in _REBUILT}
_student_classes: dict[str, type[StudentCodeError]] = {}


def student_error_class(bases: list[str]) -> type[StudentCodeError]:
    """The class a student exception is re-raised as, from its builtin base class names.

    The first name that is a rebuildable builtin wins (``LinAlgError`` arrives
    as ``["ValueError", "Exception", ...]``); without one, StudentCodeError.
    """
    for name in bases:
        builtin = _BUILTIN_BY_NAME.get(name)
        if builtin is None or getattr(builtins, name, None) is not builtin:
            continue
        cls = _student_classes.get(name)
        if cls is None:
            cls = type(f"Student{name}", (StudentCodeError, builtin), {"__module__": __name__})
            _student_classes[name] = cls
        return cls
    return StudentCodeError


# --- limits ------------------------------------------------------------------------------------


@dataclass
class Limits:
    """Resource limits of a worker.

    Attributes
    ----------
    cpu_seconds : float
        CPU time per call (and for loading the notebook).
    wall_seconds : float
        Wall-clock time per call (and for loading the notebook).
    memory_bytes : int
        Address space of the worker (RLIMIT_AS).
    max_processes : int
        Processes and threads of the worker's uid (RLIMIT_NPROC).
    max_output_bytes : int
        stdout + stderr kept per submission; the rest is counted and dropped.
    total_wall_seconds : float or None
        Wall-clock time of all of a submission's calls together; once spent,
        its remaining calls fail at once. None: :data:`BUDGET_CALLS` times
        ``wall_seconds``; a lab whose hidden tests state the reference's time
        (``REFERENCE_SECONDS``) gets :func:`reference_budget` of it.
    """

    cpu_seconds: float = 30.0
    wall_seconds: float = 60.0
    memory_bytes: int = 2 * 2**30
    max_processes: int = 64
    max_output_bytes: int = 2**20
    total_wall_seconds: float | None = None

    @property
    def budget_seconds(self) -> float:
        """The total wall time of a submission's calls."""
        if self.total_wall_seconds is not None:
            return self.total_wall_seconds
        return BUDGET_CALLS * self.wall_seconds


def reference_budget(limits: Limits, reference_seconds: float) -> float:
    """A submission's total call time: a few times the reference's, bounded both ways.

    ``max(MIN_BUDGET_SECONDS, BUDGET_FACTOR * reference_seconds)``, but never more than the
    default :attr:`Limits.budget_seconds` (``BUDGET_CALLS`` per-call wall limits). The floor
    keeps a correct but slower solution (or a loaded grading machine) from losing points.
    """
    if not reference_seconds > 0:
        raise ValueError(f"reference_seconds must be > 0, got {reference_seconds!r}")
    return min(limits.budget_seconds, max(MIN_BUDGET_SECONDS, BUDGET_FACTOR * reference_seconds))


# --- output ------------------------------------------------------------------------------------


class _Output:
    """A bounded buffer for what student code prints, shared by successive workers."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.data = bytearray()
        self.dropped = 0
        self.lock = threading.Lock()

    def drain(self, fd: int) -> None:
        # Reads until end of file, keeping only `limit` bytes: a flood never
        # fills the grader's memory and never blocks the worker on a full pipe.
        try:
            while True:
                chunk = os.read(fd, 1 << 16)
                if not chunk:
                    break
                with self.lock:
                    room = self.limit - len(self.data)
                    self.data += chunk[: max(room, 0)]
                    self.dropped += max(len(chunk) - max(room, 0), 0)
        finally:
            os.close(fd)

    def text(self) -> str:
        with self.lock:
            text = self.data.decode("utf-8", errors="replace")
            if self.dropped:
                text += f"\n[... {self.dropped} more bytes of output were dropped]\n"
        return text


# --- one worker process ------------------------------------------------------------------------


class _Worker:
    """One running worker: start, exchange messages under deadlines, kill everything."""

    def __init__(self, limits: Limits, output: _Output) -> None:
        self.limits = limits
        self.base = Path(tempfile.mkdtemp(prefix="robolab-worker-"))
        os.chmod(self.base, 0o711)  # a dropped uid must reach its work directory
        workdir = self.base / "work"
        workdir.mkdir()
        repository = Path(robolab.__file__).resolve().parent.parent
        self.plan = sandbox.plan_sandbox(
            workdir,
            readonly=[Path(robolab.__file__).resolve().parent, Path(robolab.DATA_DIR)],
            forbidden=[repository / "solutions", repository / "tests"],
            cpu_seconds=limits.cpu_seconds,
            memory_bytes=limits.memory_bytes,
            max_processes=limits.max_processes,
        )
        request_r, self.request_w = os.pipe()
        self.response_r, response_w = os.pipe()
        output_r, output_w = os.pipe()
        env = {
            "PATH": "/usr/bin:/bin",
            "HOME": str(workdir),
            "TMPDIR": str(workdir),
            "LANG": "C.UTF-8",
            "MPLBACKEND": "Agg",
            "MPLCONFIGDIR": str(workdir / ".matplotlib"),
            # One BLAS thread: threads count against the process limit, and the
            # sandbox must be applied while the worker is single-threaded.
            "OPENBLAS_NUM_THREADS": "1",
            "OMP_NUM_THREADS": "1",
            "MKL_NUM_THREADS": "1",
            # Ray casting on its numpy path: numba's on-disk kernel cache cannot be
            # written from here (read-only package, fresh HOME), so every worker would
            # compile the kernels anew (seconds of CPU); the ranges are the same.
            "ROBOLAB_RAYCAST": "numpy",
        }
        try:
            self.process = _launch(self.plan, env, workdir, (request_r, response_w, output_w))
        finally:
            for fd in (request_r, response_w, output_w):
                os.close(fd)
        self.uid = sandbox.worker_uid(self.process.pid) if self.plan.drop_privileges else None
        #: CPU time of the worker's whole process group, and the sweep after each call.
        self.clock = processes.GroupClock(self.process.pid)
        self._finalizer = weakref.finalize(
            self, _reap, self.process, self.uid, (self.request_w, self.response_r), self.base
        )
        self.drainer = threading.Thread(
            target=output.drain,
            args=(output_r,),
            daemon=True,
            name=f"robolab-worker-{self.process.pid}-output",
        )
        self.drainer.start()
        self.report: sandbox.SandboxReport | None = None
        #: Wall-time budget of the current request (for the timeout message).
        self.wall_seconds = limits.wall_seconds
        self.calls = 0

    # -- messages --

    def send(self, message: tuple, deadline: float) -> None:
        """Send a request; CPU time and new processes count against it from now on."""
        self.clock.start_call()  # before the worker can act on the request
        payload = pickle.dumps(message, protocol=5)
        frame = memoryview(HEADER.pack(len(payload)) + payload)
        poller = select.poll()
        poller.register(self.request_w, select.POLLOUT)
        while frame:
            self._check_time(deadline, None)
            if not poller.poll(POLL_SECONDS * 1000):
                self._check_alive()
                continue
            try:
                written = os.write(self.request_w, frame[: 1 << 16])
            except BrokenPipeError:
                self._check_alive(force=True)
                raise
            frame = frame[written:]

    def receive(self, deadline: float, cpu_limit: float | None) -> Any:
        """The next message, decoded with the codec, within the wall and CPU limits."""
        buffer = bytearray()
        size: int | None = None
        poller = select.poll()
        poller.register(self.response_r, select.POLLIN)
        while size is None or len(buffer) < size:
            self._check_time(deadline, cpu_limit)
            if not poller.poll(POLL_SECONDS * 1000):
                self._check_alive()
                continue
            chunk = os.read(self.response_r, 1 << 20)
            if not chunk:
                self._check_alive(force=True)
            buffer += chunk
            if size is None and len(buffer) >= HEADER.size:
                size = HEADER.size + HEADER.unpack_from(buffer)[0]
                if size > MAX_MESSAGE_BYTES + HEADER.size:
                    raise StudentCodeError(
                        f"the result is too large ({size - HEADER.size} bytes; "
                        f"at most {MAX_MESSAGE_BYTES} are accepted)",
                        kind="result",
                    )
        if len(buffer) > size:
            raise StudentCodeError(
                "the worker sent more than one answer to one request", kind="protocol"
            )
        # Decoding is the grader's CPU, spent on this submission's behalf: it is
        # charged to the call (the codec bounds it to a small multiple of the size).
        started = decode_clock()
        try:
            return codec.loads(bytes(buffer[HEADER.size :]))
        finally:
            self._end_call(cpu_limit, decode_clock() - started)

    def _end_call(self, cpu_limit: float | None, decoding: float = 0.0) -> None:
        """Kill what the call started, charging its CPU and ``decoding``; check the scratch."""
        cpu, _ = self.clock.sweep()
        if cpu_limit is not None and cpu + decoding > cpu_limit:
            self.kill()
            raise WorkerTimeout(
                f"timed out: used more than {cpu_limit:g} s of CPU time "
                f"(with the processes it started: {cpu:.1f} s; "
                f"decoding its result: {decoding:.1f} s)",
                kind="timeout",
            )
        if self.report is not None and self.report.scratch != "tmpfs":
            used = sandbox.directory_bytes(self.plan.workdir, sandbox.WORKDIR_BYTES)
            if used > sandbox.WORKDIR_BYTES:
                self.kill()
                raise WorkerCrashed(
                    f"wrote more than {sandbox.WORKDIR_BYTES // 2**20} MiB of files "
                    "to its work directory",
                    kind="crash",
                )

    # -- limits and death --

    def cpu_seconds(self) -> float:
        """CPU time used by the worker process itself, read from the kernel (trusted)."""
        try:
            with open(f"/proc/{self.process.pid}/stat", "rb") as f:
                fields = f.read().rsplit(b")", 1)[1].split()
        except (OSError, IndexError):
            return 0.0
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def _check_time(self, deadline: float, cpu_limit: float | None) -> None:
        if time.monotonic() > deadline:
            self.kill()
            raise WorkerTimeout(
                f"timed out: took longer than {self.wall_seconds:g} s of wall time",
                kind="timeout",
            )
        if cpu_limit is not None and self.clock.used() > cpu_limit:
            self.kill()
            raise WorkerTimeout(
                f"timed out: used more than {cpu_limit:g} s of CPU time "
                "(counting the processes it started)",
                kind="timeout",
            )

    def _check_alive(self, force: bool = False) -> None:
        if self.process.poll() is None and not force:
            return
        if self.process.poll() is None:
            try:  # end of file usually means it is exiting: give it a moment to be reaped
                self.process.wait(timeout=1)
            except subprocess.TimeoutExpired:
                pass
        if self.process.poll() is None:
            # The response pipe closed but the process lives: it broke the protocol.
            self.kill()
            raise WorkerCrashed("the worker closed its connection to the grader", kind="crash")
        code = self.process.returncode
        self.kill()
        if code == -signal.SIGXCPU:
            raise WorkerTimeout(
                f"timed out: used more than {self.limits.cpu_seconds:g} s of CPU time",
                kind="timeout",
            )
        if code < 0:
            name = signal.Signals(-code).name if -code in signal.valid_signals() else str(-code)
            raise WorkerCrashed(f"the worker process was killed by signal {name}", kind="crash")
        raise WorkerCrashed(
            f"the worker process exited with status {code} (os._exit, sys.exit or a fatal error)",
            kind="crash",
        )

    def kill(self) -> None:
        """Kill the worker and everything it started; idempotent."""
        _kill_tree(self.process, self.uid)

    def close(self) -> None:
        """Kill, close the pipes, remove the temporary directory; idempotent."""
        self._finalizer()
        self.drainer.join(timeout=5)


def _launch(
    plan: sandbox.SandboxPlan, env: dict[str, str], workdir: Path, pipes: tuple[int, int, int]
) -> Any:
    """Fork a warm worker from the zygote (:mod:`~.isolation.zygote`), else start one cold.

    Either way the worker runs :func:`robolab.grading.isolation.worker.main` in its own
    session, with ``pipes`` (request read end, response and output write ends).
    """
    from robolab.grading.isolation import warm

    for attempt in range(2):
        workers = warm.shared()
        if workers is None:
            break
        try:
            return workers.spawn({"plan": plan.to_dict(), "env": env, "cwd": str(workdir)}, pipes)
        except warm.ZygoteError as exc:
            warm.reset_shared(None)  # it died or broke: the next attempt starts a fresh one
            if attempt:
                warnings.warn(f"robolab grading: this worker starts cold: {exc}", stacklevel=3)
    # Cold: a fresh interpreter, seeded with the font cache so it does not rebuild it.
    plan.seed_files = {f".matplotlib/{p.name}": str(p) for p in _matplotlib_font_caches()}
    request_r, response_w, output_w = pipes
    config = {"request_fd": request_r, "response_fd": response_w, "plan": plan.to_dict()}
    return subprocess.Popen(
        [sys.executable, "-I", "-B", "-m", "robolab.grading.isolation.worker", _json(config)],
        stdin=subprocess.DEVNULL,
        stdout=output_w,
        stderr=output_w,
        pass_fds=(request_r, response_w),
        cwd=workdir,
        env=env,
        start_new_session=True,  # its own session and process group, killed as a group
    )


def _kill_tree(process: subprocess.Popen, uid: int | None) -> None:
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    if uid is not None:
        # Children that left the process group (setsid) still run as the worker's uid.
        _kill_uid(uid)
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:  # pragma: no cover - SIGKILL does not fail
        pass


def _reap(process: subprocess.Popen, uid: int | None, fds: tuple[int, ...], base: Path) -> None:
    """Everything a worker leaves behind, undone (also at exit for a proxy never closed)."""
    _kill_tree(process, uid)
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass
    shutil.rmtree(base, ignore_errors=True)


def _matplotlib_font_caches() -> list[Path]:
    """The grader's matplotlib font cache files (built once if missing)."""
    try:
        import matplotlib
    except ImportError:
        return []
    found = sorted(Path(matplotlib.get_cachedir()).glob("fontlist-v*.json"))
    if not found:
        try:
            import matplotlib.font_manager  # noqa: F401 - builds and saves the cache
        except Exception:  # noqa: BLE001 - no cache only costs the worker time
            return []
        found = sorted(Path(matplotlib.get_cachedir()).glob("fontlist-v*.json"))
    return found


def _kill_uid(uid: int) -> None:
    """SIGKILL every process of ``uid`` (root only): kill(-1) sent as that uid."""
    for _ in range(2):  # a second pass catches a child forked during the first
        pid = os.fork()
        if pid == 0:  # pragma: no cover - runs in the child
            try:
                os.setgroups([])
                os.setgid(uid)
                os.setuid(uid)
                os.kill(-1, signal.SIGKILL)
            finally:
                os._exit(0)
        os.waitpid(pid, 0)


def _json(value: Any) -> str:
    import json

    return json.dumps(value)


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
    """

    def __init__(self, notebook: LoadedNotebook, lab: str | None, limits: Limits) -> None:
        self.lab = lab
        self.path = notebook.path
        # The parsed names until the worker reports what actually got defined.
        self.functions: list[str] = list(notebook.functions)
        self.problems: list[CellProblem] = list(notebook.problems)
        self.sandbox: sandbox.SandboxReport | None = None
        self._notebook = notebook
        self._limits = limits
        self._output = _Output(limits.max_output_bytes)
        self._worker: _Worker | None = None
        self._broken: StudentCodeError | None = None
        self._call_id = 0
        self._closed = False
        self._loaded = False
        self._timed_out: set[str] = set()
        #: Wall seconds spent in calls so far (against ``limits.budget_seconds``).
        self.spent_seconds = 0.0

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name.startswith("_"):
            raise AttributeError(name)
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

    def _start(self) -> _Worker:
        """A fresh worker with the notebook's definitions loaded."""
        worker = _Worker(self._limits, self._output)
        try:
            message = worker.receive(time.monotonic() + STARTUP_SECONDS, None)
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
        try:
            deadline = time.monotonic() + self._limits.wall_seconds
            budget = load_budget(self._limits.wall_seconds, self._limits.cpu_seconds)
            worker.send(("define", self._notebook.cells, *budget), deadline)
            message = self._expect(
                worker, worker.receive(deadline, self._limits.cpu_seconds), "defined"
            )
        except (StudentCodeError, codec.CodecError, BrokenPipeError) as exc:
            if not isinstance(exc, StudentCodeError):
                exc = StudentCodeError(f"the worker broke the protocol: {exc}", kind="protocol")
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
        return worker

    def _expect(self, worker: _Worker, message: Any, kind: str, call_id: int | None = None) -> Any:
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
            pickle.dumps((args, kwargs), protocol=5)
        except Exception as exc:
            raise TypeError(f"arguments to {name}() cannot be sent to the worker: {exc}") from exc
        if self.spent_seconds >= self._limits.budget_seconds:
            raise WorkerTimeout(
                f"{name}() was not run: the submission used up its total time budget "
                f"of {self._limits.budget_seconds:g} s",
                kind="timeout",
            )
        worker = self._worker
        if (
            worker is not None
            and worker.cpu_seconds()
            > worker.plan.cpu_lifetime_seconds - self._limits.cpu_seconds - 1
        ):
            self._discard()  # restart before the lifetime CPU limit could cut a fair call short
            worker = None
        if worker is None:
            worker = self._worker = self._start()
        self._call_id += 1
        call_id = self._call_id
        wall, cpu = self._limits.wall_seconds, self._limits.cpu_seconds
        if name in self._timed_out:
            # It ran out of time before: it most likely will again, and each try
            # would cost a full wall limit. A small input still gets its answer.
            wall, cpu = min(wall, max(1.0, wall / 10)), min(cpu, max(1.0, cpu / 10))
        left = self._limits.budget_seconds - self.spent_seconds
        budget_bound = left < wall
        wall = min(wall, left)
        worker.wall_seconds = wall
        started = time.monotonic()
        deadline = started + wall
        try:
            worker.send(("call", call_id, name, args, kwargs, cpu), deadline)
            message = worker.receive(deadline, cpu)
        except codec.CodecError as exc:
            self._discard()
            raise StudentCodeError(
                f"{name}() returned a value the grader does not accept: {exc}", kind="result"
            ) from None
        except (StudentCodeError, BrokenPipeError) as exc:
            self._discard()
            if isinstance(exc, WorkerTimeout):
                self._timed_out.add(name)
                if budget_bound and time.monotonic() >= deadline:
                    exc = WorkerTimeout(
                        f"timed out: the submission used up its total time budget of "
                        f"{self._limits.budget_seconds:g} s",
                        kind="timeout",
                    )
            if isinstance(exc, BrokenPipeError):
                raise WorkerCrashed(
                    f"the worker died before {name}() could run", kind="crash"
                ) from None
            raise type(exc)(
                f"{name}(): {exc.message}", kind=exc.kind, student_traceback=exc.student_traceback
            ) from None
        finally:
            self.spent_seconds += time.monotonic() - started
        return self._answer(worker, name, call_id, message, args, kwargs)

    def _answer(
        self,
        worker: _Worker,
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
        if self._worker is not None:
            self._worker.close()
            self._worker = None


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
    path: str | Path, lab: str | None = None, *, limits: Limits | None = None
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
    proxy = SubmissionProxy(notebook, lab or notebook.lab, limits or Limits())
    try:
        proxy._worker = proxy._start()
    except StudentCodeError:
        pass  # recorded in proxy.problems; every call raises it again
    return proxy
