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
import dataclasses
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
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import robolab
from robolab.grading.isolation import processes, sandbox
from robolab.grading.isolation.worker import HEADER
from robolab.grading.loading.kernel import load_budget
from robolab.grading.loading.notebook import CellProblem, LoadedNotebook, load_notebook
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

#: Without ``Limits.total_cpu_seconds`` / ``total_wall_seconds``, a submission (its loads
#: and calls together) may use this many per-call limits in total.
BUDGET_CALLS = 5
#: A lab whose hidden tests state ``REFERENCE_CPU_SECONDS`` (the CPU time the reference
#: solution's worker uses while graded) gives a submission this many times that in CPU
#: time, at least :data:`MIN_CPU_BUDGET_SECONDS` (never more than :data:`BUDGET_CALLS`
#: per-call limits): see :func:`reference_limits`. A correct solution 5x slower than the
#: reference fits with room to spare (CPU time itself grows a little on a busy machine).
BUDGET_FACTOR = 8.0
MIN_CPU_BUDGET_SECONDS = 20.0
#: The wall-time backstop of a submission with a reference: this many times its CPU budget,
#: at least :data:`MIN_BUDGET_SECONDS`, counted net of waiting for a CPU
#: (:class:`~robolab.grading.isolation.processes.AwakeClock`): it stops a submission that sleeps,
#: never one that computes or waits for a core.
WALL_FACTOR = 2.0
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


class ScratchExceeded(WorkerCrashed):
    """A call wrote more files than its work directory may hold (without the tmpfs view)."""


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
        CPU time per call (and for loading the notebook), the processes it starts included.
    wall_seconds : float
        Wall-clock time per call (and for loading the notebook), a backstop against
        sleeping or stalled code: counted net of the time the worker (and the grader
        waiting for it) spent waiting for a CPU, so a busy machine never reaches it.
    memory_bytes : int
        Address space of the worker (RLIMIT_AS).
    max_processes : int
        Processes and threads of the worker's uid (RLIMIT_NPROC).
    max_output_bytes : int
        stdout + stderr kept per submission; the rest is counted and dropped.
    total_wall_seconds : float or None
        Wall-clock backstop of a whole submission (every load of the notebook and
        every call), counted like ``wall_seconds``; once spent, its remaining calls
        fail at once. None: :data:`BUDGET_CALLS` times ``wall_seconds``.
    total_cpu_seconds : float or None
        CPU time of a whole submission (every load and every call, the processes
        they start included): what decides "too slow". None: :data:`BUDGET_CALLS`
        times ``cpu_seconds``; a lab whose hidden tests state the reference's CPU
        time (``REFERENCE_CPU_SECONDS``) gets :func:`reference_limits` of it.
    """

    cpu_seconds: float = 30.0
    wall_seconds: float = 60.0
    memory_bytes: int = 2 * 2**30
    max_processes: int = 64
    max_output_bytes: int = 2**20
    total_wall_seconds: float | None = None
    total_cpu_seconds: float | None = None

    @property
    def budget_seconds(self) -> float:
        """The wall-time backstop of a whole submission (net of waiting for a CPU)."""
        if self.total_wall_seconds is not None:
            return self.total_wall_seconds
        return BUDGET_CALLS * self.wall_seconds

    @property
    def cpu_budget_seconds(self) -> float:
        """The CPU time of a whole submission: loads and calls, children included."""
        if self.total_cpu_seconds is not None:
            return self.total_cpu_seconds
        return BUDGET_CALLS * self.cpu_seconds


def reference_limits(limits: Limits, reference_cpu_seconds: float) -> Limits:
    """``limits`` with the totals a lab's reference CPU time gives (those not set already).

    CPU: ``max(MIN_CPU_BUDGET_SECONDS, BUDGET_FACTOR * reference_cpu_seconds)``; the wall
    backstop: ``max(MIN_BUDGET_SECONDS, WALL_FACTOR * cpu budget)``. Neither exceeds its
    default (``BUDGET_CALLS`` per-call limits). Both are charged with what the worker uses,
    measured as the reference was, so the grade does not depend on the machine's load.

    Raises
    ------
    ValueError
        When ``reference_cpu_seconds`` is not a positive number.
    """
    if not reference_cpu_seconds > 0:
        raise ValueError(f"reference_cpu_seconds must be > 0, got {reference_cpu_seconds!r}")
    cpu = limits.total_cpu_seconds
    if cpu is None:
        cpu = min(
            limits.cpu_budget_seconds,
            max(MIN_CPU_BUDGET_SECONDS, BUDGET_FACTOR * reference_cpu_seconds),
        )
    wall = limits.total_wall_seconds
    if wall is None:
        wall = min(limits.budget_seconds, max(MIN_BUDGET_SECONDS, WALL_FACTOR * cpu))
    return dataclasses.replace(limits, total_cpu_seconds=cpu, total_wall_seconds=wall)


# --- output ------------------------------------------------------------------------------------


class _Output:
    """A bounded buffer for what student code prints, shared by successive workers.

    A thread per worker drains its pipe as output arrives; :meth:`text` also reads
    what is already in the pipes, so what a call printed (the worker flushes before it
    answers) is there as soon as the call returns, however late the thread runs.
    """

    #: Most bytes :meth:`text` reads from a pipe itself (the drainer does the rest).
    READ_AHEAD = 1 << 22

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.data = bytearray()
        self.dropped = 0
        self.lock = threading.Lock()
        self.pipes: set[int] = set()

    def _read(self, fd: int, most: float = float("inf")) -> bool:
        """Read what ``fd`` holds now (under the lock), up to ``most`` bytes; False at its end."""
        while most > 0:
            try:
                chunk = os.read(fd, 1 << 16)
            except BlockingIOError:
                return True
            if not chunk:
                return False
            most -= len(chunk)
            room = max(self.limit - len(self.data), 0)
            self.data += chunk[:room]
            self.dropped += max(len(chunk) - room, 0)
        return True

    def drain(self, fd: int) -> None:
        # Reads until end of file, keeping only `limit` bytes: a flood never
        # fills the grader's memory and never blocks the worker on a full pipe.
        os.set_blocking(fd, False)
        poller = select.poll()
        poller.register(fd, select.POLLIN)
        with self.lock:
            self.pipes.add(fd)
        try:
            while True:
                poller.poll()
                with self.lock:
                    if not self._read(fd, 1 << 20):
                        break
        finally:
            with self.lock:
                self.pipes.discard(fd)
                os.close(fd)

    def text(self) -> str:
        with self.lock:
            for fd in self.pipes:
                self._read(fd, self.READ_AHEAD)
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
        _tell_runner(self.process.pid)
        #: CPU time of the worker's whole process group, and the sweep after each call.
        self.clock = processes.GroupClock(self.process.pid)
        #: Wall time of the current request, net of waiting for a CPU (the wall limits).
        self.awake = processes.AwakeClock(self.process.pid)
        #: CPU seconds of the current request so far (the group's, children included), and
        #: its awake seconds until its answer arrived or it was stopped (not the sweep after).
        self.request_cpu = self.request_awake = 0.0
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
        #: Wall limit of the current request (on the awake clock); first: starting up.
        self.wall_seconds = STARTUP_SECONDS
        self.calls = 0

    # -- messages --

    def send(self, message: tuple, wall_seconds: float) -> None:
        """Send a request; CPU time, wall time and new processes count against it from now on."""
        self.clock.start_call()  # before the worker can act on the request
        self.awake.restart()
        self.wall_seconds = wall_seconds
        self.request_cpu = self.request_awake = 0.0
        self.reply(message)

    def reply(self, message: tuple) -> None:
        """Send a message within the running request (the request, or a depcall's answer)."""
        before = processes.run_delay()  # until it is written, the worker waits for this thread
        payload = pickle.dumps(message, protocol=5)
        frame = memoryview(HEADER.pack(len(payload)) + payload)
        poller = select.poll()
        poller.register(self.request_w, select.POLLOUT)
        while frame:
            self._check_time(None)
            if not poller.poll(POLL_SECONDS * 1000):
                self._check_alive()
                continue
            try:
                written = os.write(self.request_w, frame[: 1 << 16])
            except BrokenPipeError:
                self._check_alive(force=True)
                raise
            frame = frame[written:]
        after = processes.run_delay()
        if before is not None and after is not None:
            self.awake.excuse(after - before)

    def receive(
        self,
        cpu_limit: float | None,
        alarm_after: float | None = None,
        on_depcall: Callable[[Any], tuple] | None = None,
    ) -> Any:
        """The next message, decoded with the codec, within the request's wall and CPU limits.

        ``alarm_after``: awake seconds after which the worker gets ``SIGALRM`` (again every
        0.5 s): the load's wall budget, which stops the cell that spends it. A
        ``("depcall", ...)`` message on the way (robolab.grading.running.answers) is answered
        with ``on_depcall(message)`` and the wait goes on, within the same limits; without
        ``on_depcall`` it is the answer, which the caller refuses as out of turn.
        """
        self._alarm_after = alarm_after
        decoding = 0.0  # the grader's CPU spent decoding on this submission's behalf
        while True:
            data = self._read_message(cpu_limit)
            # Charged to the call (the codec bounds it to a small multiple of the size).
            started = decode_clock()
            try:
                message = codec.loads(data)
            except codec.CodecError:
                self._end_call(cpu_limit, decoding + decode_clock() - started)
                raise  # a timeout is the first thing to say
            decoding += decode_clock() - started
            if on_depcall is None or not (
                isinstance(message, tuple) and message and message[0] == "depcall"
            ):
                self._end_call(cpu_limit, decoding)
                return message
            reply = on_depcall(message)
            self._check_time(cpu_limit)  # the reference's time counts for the call's wall
            self.reply(reply)

    def _read_message(self, cpu_limit: float | None) -> bytes:
        """One length-prefixed message's bytes, within the request's wall and CPU limits."""
        buffer = bytearray()
        size: int | None = None
        poller = select.poll()
        poller.register(self.response_r, select.POLLIN)
        while size is None or len(buffer) < size:
            self._check_time(cpu_limit)
            alarm = self._alarm_after
            if alarm is not None and self.request_awake > alarm:
                self._alarm_after = self.request_awake + 0.5
                try:
                    os.kill(self.process.pid, signal.SIGALRM)
                except (ProcessLookupError, PermissionError):
                    pass
            if not self._wait(poller):
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
        self.request_awake = self.awake.elapsed()
        if len(buffer) > size:
            raise StudentCodeError(
                "the worker sent more than one answer to one request", kind="protocol"
            )
        return bytes(buffer[HEADER.size :])

    def _end_call(self, cpu_limit: float | None, decoding: float = 0.0) -> None:
        """Kill what the call started, charging its CPU and ``decoding``; check the scratch."""
        cpu, _ = self.clock.sweep()
        self.request_cpu = cpu + decoding
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
                raise ScratchExceeded(
                    f"wrote more than {sandbox.WORKDIR_BYTES // 2**20} MiB of files "
                    "to its work directory",
                    kind="crash",
                )

    def _wait(self, poller: select.poll) -> bool:
        """Poll for the worker's answer; the time this thread then waited for a core, the
        worker (which is waiting for us) is excused."""
        before = processes.run_delay()
        if not poller.poll(POLL_SECONDS * 1000):
            return False
        after = processes.run_delay()
        if before is not None and after is not None:
            self.awake.excuse(after - before)
        return True


    # -- limits and death --

    def cpu_seconds(self) -> float:
        """CPU time used by the worker process itself, read from the kernel (trusted)."""
        try:
            with open(f"/proc/{self.process.pid}/stat", "rb") as f:
                fields = f.read().rsplit(b")", 1)[1].split()
        except (OSError, IndexError):
            return 0.0
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def _check_time(self, cpu_limit: float | None) -> None:
        self.request_awake = self.awake.elapsed()
        if self.request_awake > self.wall_seconds:
            self.kill()
            raise WorkerTimeout(
                f"timed out: took longer than {self.wall_seconds:g} s of wall time "
                "(not counting time spent waiting for a CPU)",
                kind="timeout",
            )
        if cpu_limit is None:
            return
        self.request_cpu = self.clock.used()
        if self.request_cpu > cpu_limit:
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


def _tell_runner(pid: int) -> None:
    """Append the worker's pid to the runner's file (:data:`processes.WORKER_PIDS_VARIABLE`)."""
    path = os.environ.get(processes.WORKER_PIDS_VARIABLE)
    if path:
        try:
            with open(path, "a", encoding="ascii") as f:
                f.write(f"{pid}\n")
        except OSError:
            pass  # the runner's timeout then counts this worker's waiting too


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
        self._output = _Output(limits.max_output_bytes)
        self._worker: _Worker | None = None
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

    def _charge(self, worker: _Worker) -> float:
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

    def _start(self) -> _Worker:
        """A fresh worker with the notebook's definitions loaded."""
        worker = _Worker(self._limits, self._output)
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
                pickle.dumps(reply, protocol=5)
            except Exception as exc:  # noqa: BLE001 - a reference value that cannot cross
                return ("own", f"the reference's answer cannot be sent: {exc}")
            return reply

        return answer

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
