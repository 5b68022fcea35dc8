"""The grader's side of warm grading: start or attach to zygotes, fork workers and pytest runs.

:mod:`robolab.grading.isolation.zygote` is the process that forks; this module is what
the grader uses: :func:`shared` (this process's worker zygote: the one whose
control socket it inherited, else one started on first use), :func:`shared_grader`
(a zygote forking the pytest runs of one project root), :class:`Zygote` (a handle:
``spawn`` sends a request and its descriptors, ``SCM_RIGHTS``) and
:class:`WarmChild` (a forked child with the parts of :class:`subprocess.Popen`
the proxy and the runner use). See ``docs/grading.md``, section 8.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import socket
import sys
import threading
import time
from collections.abc import Iterator

__all__ = [
    "FD_VARIABLE",
    "SWITCH_VARIABLE",
    "WarmChild",
    "Zygote",
    "ZygoteError",
    "probing",
    "reset_shared",
    "running_graders",
    "shared",
    "shared_grader",
]

#: Environment variable naming an inherited control socket (set by the runner for pytest).
FD_VARIABLE = "ROBOLAB_WARM_FD"
#: Set to "0" to start every worker cold (``python -m robolab.grading.isolation.worker``).
SWITCH_VARIABLE = "ROBOLAB_WARM_WORKERS"
#: Seconds the zygote may take to import :data:`PRELOAD` and fork the first worker.
STARTUP_SECONDS = 60.0
#: Grader zygotes (one per project root) a process keeps; the oldest is closed first.
MAX_GRADER_ZYGOTES = 2


class ZygoteError(RuntimeError):
    """The zygote could not be started or did not fork a worker."""


class WarmChild:
    """A worker forked by the zygote, with the parts of :class:`subprocess.Popen` the proxy uses.

    ``returncode`` is None while it runs, then its exit status (negative: the
    signal that killed it), as the zygote reports it.
    """

    def __init__(self, conn: socket.socket, pid: int, buffer: bytes) -> None:
        self.conn = conn
        self.pid = pid
        self.returncode: int | None = None
        self._buffer = buffer
        self._lock = threading.Lock()
        self._parse()

    def _parse(self) -> None:
        while b"\n" in self._buffer and self.returncode is None:
            line, self._buffer = self._buffer.split(b"\n", 1)
            message = json.loads(line)
            if "exit" in message:
                self.returncode = int(message["exit"])
                self.conn.close()

    def _read(self, timeout: float | None) -> None:
        # Poll without the lock: a thread waiting a long time for the child must not keep
        # another (stopping it on SIGTERM) from waiting a short time.
        if self.returncode is not None or not _readable(self.conn, timeout):
            return
        with self._lock:
            if self.returncode is not None:
                return
            try:
                chunk = self.conn.recv(4096, socket.MSG_DONTWAIT)
            except BlockingIOError:
                return  # another thread read it first
            except OSError:
                chunk = b""
            if not chunk:
                # The zygote died; its workers die with it (PDEATHSIG).
                self.returncode = -signal.SIGKILL
                self.conn.close()
                return
            self._buffer += chunk
            self._parse()

    def poll(self) -> int | None:
        """The exit status, or None while the worker runs."""
        self._read(0)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """Wait for the worker to exit; :class:`subprocess.TimeoutExpired` after ``timeout``."""
        import subprocess

        deadline = None if timeout is None else time.monotonic() + timeout
        while self.returncode is None:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise subprocess.TimeoutExpired(f"worker {self.pid}", timeout)
            self._read(left)
        return self.returncode


class Zygote:
    """The grader's handle on a zygote: start one, or attach to an inherited control socket.

    Parameters
    ----------
    control_fd : int, optional
        An inherited control socket (see :data:`FD_VARIABLE`); without it a
        new zygote is started, owned by this process.
    role : {"worker", "grader"}
        A worker zygote (isolated workers: a clean ``python -I`` with a minimal
        environment) or a grader zygote (pytest runs of the hidden tests, with
        the grader's environment, started in ``cwd``).
    cwd : str, optional
        The grader zygote's directory (the project root the hidden tests are in).
    env : dict, optional
        The grader zygote's environment (default: this process's).
    pass_fds : tuple of int
        Descriptors the grader zygote keeps for its children (the worker zygote's
        control socket).
    """

    def __init__(
        self,
        control_fd: int | None = None,
        *,
        role: str = "worker",
        cwd: str | None = None,
        env: dict[str, str] | None = None,
        pass_fds: tuple[int, ...] = (),
    ) -> None:
        if role not in ("worker", "grader"):
            raise ValueError(f"role must be 'worker' or 'grader', got {role!r}")
        self.process = None
        self.role = role
        self._lock = threading.Lock()
        self._ready: int | None = None
        if control_fd is not None:
            self.control = socket.socket(fileno=control_fd)
            if self.control.type != socket.SOCK_SEQPACKET:
                self.control.detach()
                raise ZygoteError(f"descriptor {control_fd} is not a zygote's control socket")
            os.set_inheritable(control_fd, False)
            return
        self.control, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        import subprocess

        # The zygote writes one byte here once it has imported everything: until then it
        # has forked nothing, and close() may simply kill it instead of waiting.
        self._ready, ready_w = os.pipe()
        os.set_blocking(self._ready, False)
        config = json.dumps({"control_fd": theirs.fileno(), "role": role, "ready_fd": ready_w})
        if role == "worker":  # exactly like a cold worker: isolated mode, minimal environment
            argv = [sys.executable, "-I", "-B", "-m", "robolab.grading.isolation.zygote", config]
            env, cwd = _zygote_env(), "/"
        else:
            argv = [sys.executable, "-m", "robolab.grading.isolation.zygote", config]
            env = dict(os.environ if env is None else env)
            for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
                env.setdefault(name, "1")  # single-threaded, or it could not fork safely
        try:
            self.process = subprocess.Popen(
                argv,
                stdin=subprocess.DEVNULL,
                pass_fds=(theirs.fileno(), ready_w, *pass_fds),
                env=env,
                cwd=cwd,
                start_new_session=True,  # a Ctrl-C in the grader's terminal reaches the grader only
            )
        finally:
            theirs.close()
            os.close(ready_w)
        # No waiting here: it imports while the grader starts up, and the first
        # request simply queues until it is ready.

    def fileno(self) -> int:
        """The control socket, to pass to a grading process (with :data:`FD_VARIABLE`)."""
        return self.control.fileno()

    def spawn(self, request: dict, fds: tuple[int, ...]) -> WarmChild:
        """Fork a child: a worker or a pytest run, as the request says.

        A worker's request is ``{"plan", "env", "cwd"}`` with ``fds`` = (request
        read end, response write end, output write end); a pytest run's is
        ``{"args", "env", "cwd", "keep"}`` with ``fds`` = (log,), ``keep`` naming
        descriptors of the grader zygote its child keeps. The caller keeps (and
        closes) its copies of ``fds``.

        Returns
        -------
        WarmChild
            The child, already running.

        Raises
        ------
        ZygoteError
            When the zygote is gone or refuses.
        """
        if getattr(_probing, "active", False):
            request = dict(request, probe=True)
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            with self._lock:
                socket.send_fds(
                    self.control, [json.dumps(request).encode()], [theirs.fileno(), *fds]
                )
        except OSError as exc:
            ours.close()
            raise ZygoteError(f"the zygote is gone: {exc}") from exc
        finally:
            theirs.close()
        buffer = b""
        deadline = time.monotonic() + STARTUP_SECONDS
        while b"\n" not in buffer:
            left = deadline - time.monotonic()
            chunk = ours.recv(4096) if _readable(ours, max(left, 0)) else b""
            if not chunk:
                ours.close()
                raise ZygoteError("the zygote did not fork (it has exited or hangs)")
            buffer += chunk
        line, rest = buffer.split(b"\n", 1)
        answer = json.loads(line)
        if "pid" not in answer:
            ours.close()
            raise ZygoteError(f"the zygote did not fork: {answer.get('error')}")
        return WarmChild(ours, int(answer["pid"]), rest)

    def close(self) -> None:
        """Close this handle; a zygote this process started exits (killing its children)."""
        try:
            self.control.close()
        except OSError:
            pass
        if self._ready is not None:
            try:
                preloaded = os.read(self._ready, 1) != b""
            except BlockingIOError:
                preloaded = False  # still importing: it has forked nothing yet
            except OSError:
                preloaded = True
            os.close(self._ready)
            self._ready = None
            if not preloaded and self.process is not None and self.process.poll() is None:
                # A command that ends (an error, --help) before its zygote is ready does not
                # wait half a second for imports nobody will use.
                self.process.kill()
        if self.process is not None:
            try:
                self.process.wait(timeout=15)
            except Exception:  # noqa: BLE001 - it will not outlive a closed control socket
                self.process.kill()
                self.process.wait()


def _readable(sock: socket.socket, timeout: float | None) -> bool:
    """Whether ``sock`` has data or end of file within ``timeout`` seconds (None: forever)."""
    poller = select.poll()
    poller.register(sock, select.POLLIN)
    return bool(poller.poll(None if timeout is None else max(0, int(timeout * 1000))))


def _zygote_env() -> dict[str, str]:
    """The worker's minimal environment, plus where the grader's matplotlib cache is."""
    env = {
        "PATH": "/usr/bin:/bin",
        "LANG": "C.UTF-8",
        "MPLBACKEND": "Agg",
        # One BLAS thread: the zygote must stay single-threaded to fork safely.
        "OPENBLAS_NUM_THREADS": "1",
        "OMP_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1",
    }
    for name in ("HOME", "XDG_CACHE_HOME", "XDG_CONFIG_HOME", "MPLCONFIGDIR"):
        if name in os.environ:
            env[name] = os.environ[name]
    return env


_probing = threading.local()


@contextlib.contextmanager
def probing() -> Iterator[None]:
    """Mark the workers this thread forks meanwhile as probes (:mod:`~.isolation.protection`).

    A probe is forked and isolated like any worker; it only does not count as a
    submission of the batch for the zygote's idle imports
    (:data:`~robolab.grading.isolation.zygote.IDLE_AFTER`).
    """
    previous = getattr(_probing, "active", False)
    _probing.active = True
    try:
        yield
    finally:
        _probing.active = previous


_shared: Zygote | None = None
_shared_failed: str | None = None
_graders: dict[str, Zygote] = {}
_shared_lock = threading.Lock()


def _enabled() -> bool:
    return (
        os.environ.get(SWITCH_VARIABLE) != "0"
        and hasattr(os, "fork")
        and hasattr(socket, "send_fds")
        and sys.platform == "linux"
    )


def _cold(exc: Exception) -> None:
    import warnings

    warnings.warn(f"robolab grading: starting cold: {exc}", stacklevel=3)


def shared() -> Zygote | None:
    """This process's worker zygote: the inherited one, else one started on first use.

    None (workers start cold) when :data:`SWITCH_VARIABLE` is ``"0"``, when
    fork or descriptor passing is unavailable, or after a zygote failed to
    start (a warning says why).
    """
    global _shared, _shared_failed
    if not _enabled():
        return None
    with _shared_lock:
        if (
            _shared is not None
            and _shared.process is not None
            and _shared.process.poll() is not None
        ):
            _shared.close()  # it died (killed, out of memory): start a fresh one
            _shared = None
        if _shared is not None or _shared_failed is not None:
            return _shared
        inherited = os.environ.pop(FD_VARIABLE, None)
        try:
            if inherited is not None:
                try:
                    _shared = Zygote(int(inherited))
                    return _shared
                except (ValueError, OSError, ZygoteError):
                    pass  # not ours after all (a stale variable): start one of our own
            _shared = Zygote()
        except (OSError, ZygoteError) as exc:
            _shared_failed = str(exc)
            _cold(exc)
            return None
        import atexit

        atexit.register(_shared.close)
        return _shared


def shared_grader(root: str, env: dict[str, str]) -> Zygote | None:
    """This process's grader zygote for the project at ``root`` (started on first use).

    Its children are pytest runs of the hidden tests (``Zygote.spawn`` with
    ``{"args", "env", "cwd", "keep"}``); they reach this process's worker
    zygote through the inherited control socket. None when warm grading is off.
    """
    workers = shared()
    if workers is None:
        return None
    with _shared_lock:
        grader = _graders.get(root)
        if grader is not None and grader.process.poll() is not None:
            _graders.pop(root).close()  # it died: start a fresh one
            grader = None
        if grader is None:
            while len(_graders) >= MAX_GRADER_ZYGOTES:  # one per project root, few roots at once
                _graders.pop(next(iter(_graders))).close()
            env = dict(env, **{FD_VARIABLE: str(workers.fileno())})
            try:
                grader = Zygote(role="grader", cwd=root, env=env, pass_fds=(workers.fileno(),))
            except (OSError, ZygoteError) as exc:
                _cold(exc)
                return None
            import atexit

            atexit.register(grader.close)  # before the worker zygote's close (last in, first out)
            _graders[root] = grader
        return grader


def running_graders() -> list[tuple[str, Zygote]]:
    """The grader zygotes this process started that still run, with their project roots
    (newest first)."""
    with _shared_lock:
        return [
            (root, grader)
            for root, grader in reversed(_graders.items())
            if grader.process is not None and grader.process.poll() is None
        ]


def reset_shared(zygote: Zygote | None = None) -> None:
    """Close this process's zygotes; ``zygote`` is the worker zygote next (tests, benchmarks)."""
    global _shared, _shared_failed
    with _shared_lock:
        for grader in _graders.values():
            grader.close()
        _graders.clear()
        if _shared is not None and _shared is not zygote:
            _shared.close()
        _shared, _shared_failed = zygote, None
