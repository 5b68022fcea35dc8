"""Warm grading workers: a clean process that imports the libraries once and forks workers.

Starting a worker cold costs an interpreter start, numpy, and then whatever the
notebook imports (``matplotlib.pyplot``, ``robolab.plotting``, scipy): most of
the time it takes to grade a small lab. The *zygote* pays that once. It is
started exactly like a worker (``python -I -B -m robolab.grading.zygote``, a
minimal environment, no current directory on ``sys.path``), imports
:data:`PRELOAD`, and then, for each worker the grader asks for, forks a child
that becomes the worker: it gets its own session, its pipes, working directory
and environment, and runs :func:`robolab.grading.worker.main`, which isolates
it (:func:`robolab.grading.sandbox.apply`: namespaces, view, uid, limits,
Landlock) before any student code exists in it -- the same code path as a cold
worker, so isolation is unchanged.

A forked child inherits the zygote's memory, so the zygote must never hold
anything a submission may not see: it never imports ``solutions`` or ``tests``
(the meta-path hook of the worker refuses them in the zygote too), never reads
the hidden tests, and keeps no state between forks. Each child is a fresh copy
of the freshly started zygote: what one submission changes (monkeypatched numpy,
globals, random state) is gone for the next. numpy's global random state is
reseeded in every child.

Protocol. The zygote listens on one ``SOCK_SEQPACKET`` socket (*control*), of
which graders hold the other end (a socketpair: the runner passes it to its
pytest processes by descriptor, never by a path another process could open).
A request is one message: JSON ``{"plan", "env", "cwd"}`` with four descriptors
attached (``SCM_RIGHTS``): a private stream socket back to the grader (*conn*),
the worker's request pipe, its response pipe and its output pipe. On *conn*
the zygote answers ``{"pid": N}`` (or ``{"error": text}``) and later
``{"exit": code}`` (a :class:`subprocess.Popen`-style return code) once the
worker is reaped. When *conn* closes first -- the grader died -- the zygote
kills the worker's process group and uid. When every holder of the control
socket is gone, the zygote kills every worker it started and exits.
"""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import sys
import threading
import time

__all__ = [
    "PRELOAD",
    "WarmChild",
    "Zygote",
    "ZygoteError",
    "reset_shared",
    "shared",
    "shared_grader",
]

#: Modules the zygote imports before it forks the first worker: what every lab's notebook uses.
PRELOAD = (
    "numpy",
    "matplotlib",
    "matplotlib.pyplot",
    "fractions",
    "robolab.grading.codec",
    "robolab.geometry",
    "robolab.validation",
    "robolab.maps",
    "robolab.raycast",
    "robolab.plotting",
    "robolab.checks",
)
#: Modules some labs use, imported one at a time while the zygote has nothing to do once it
#: has served :data:`IDLE_AFTER` requests: a single submission neither waits for them nor
#: pays for them, a batch gets them warm.
PRELOAD_IDLE = (
    "scipy.special",
    "scipy.ndimage",
    "scipy.integrate",
    "tqdm.auto",
    "robolab.bag",
    "robolab.world",
    "robolab.fiducials",
    "filterpy.kalman",
)
#: Requests served before the idle imports start (a batch, not one submission).
IDLE_AFTER = 2
#: What the grader zygote (the trusted side: pytest, the hidden tests) imports before forking.
GRADER_PRELOAD = (
    "numpy",
    "pytest",
    "_pytest.python",
    "_pytest.fixtures",
    "_pytest.assertion.rewrite",
    "fractions",
    "robolab.grading.proxy",
)
#: ... and while it is idle: what the hidden tests and reference solutions import.
GRADER_PRELOAD_IDLE = (
    "scipy.special",
    "scipy.ndimage",
    "scipy.integrate",
    "scipy.stats",
    "robolab.maps",
    "robolab.raycast",
    "robolab.bag",
    "robolab.world",
    "robolab.fiducials",
    "filterpy.kalman",
)
#: Environment variable naming an inherited control socket (set by the runner for pytest).
FD_VARIABLE = "ROBOLAB_WARM_FD"
#: Set to "0" to start every worker cold (``python -m robolab.grading.worker``).
SWITCH_VARIABLE = "ROBOLAB_WARM_WORKERS"
#: Seconds the zygote may take to import :data:`PRELOAD` and fork the first worker.
STARTUP_SECONDS = 60.0
#: Grader zygotes (one per project root) a process keeps; the oldest is closed first.
MAX_GRADER_ZYGOTES = 2
#: Largest request (JSON) accepted by the zygote.
MAX_REQUEST_BYTES = 1 << 20


class ZygoteError(RuntimeError):
    """The zygote could not be started or did not fork a worker."""


# --- the zygote process ------------------------------------------------------------------------


def _preload(role: str) -> None:
    if role == "worker":
        from robolab.grading.worker import RefuseAnswers

        sys.meta_path.insert(0, RefuseAnswers())  # the answers can never be in a child's memory
        import matplotlib

        matplotlib.use("Agg")
    for name in PRELOAD if role == "worker" else GRADER_PRELOAD:
        _import(name)
    _freeze()


def _freeze() -> None:
    """Move every object so far out of the collector's reach (what ``gc.freeze`` is for).

    A child's garbage collections then skip the preloaded modules' objects:
    faster, and the child does not write to (and so copy) every page it shares
    with the zygote.
    """
    import gc

    gc.collect()
    gc.freeze()


def _import(name: str) -> None:
    import importlib

    try:
        importlib.import_module(name)
    except ImportError:
        pass  # an optional library that is not installed: the worker reports it if used


def _threads() -> int:
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return threading.active_count()


class _Server:
    """The zygote's loop: fork a worker per request, report its exit, kill orphans."""

    def __init__(self, control: socket.socket, role: str) -> None:
        self.control = control
        self.role = role
        self.conns: dict[int, socket.socket] = {}  # worker pid -> its grader's connection
        self.served = 0
        self.wake_r, self.wake_w = os.pipe()
        os.set_blocking(self.wake_w, False)
        os.set_blocking(self.wake_r, False)
        signal.signal(signal.SIGCHLD, lambda *_: None)
        signal.set_wakeup_fd(self.wake_w)

    def run(self) -> int:
        poller = select.poll()
        poller.register(self.control, select.POLLIN)
        poller.register(self.wake_r, select.POLLIN)
        by_fd: dict[int, int] = {}
        idle = list(PRELOAD_IDLE if self.role == "worker" else GRADER_PRELOAD_IDLE)
        while True:
            warm_up = idle and self.served >= IDLE_AFTER
            try:
                events = poller.poll(0 if warm_up else 1000)
            except InterruptedError:  # pragma: no cover - poll retries on EINTR since 3.5
                continue
            if not events and warm_up:
                _import(idle.pop(0))
                _freeze()
                continue
            for fd, _ in events:
                if fd == self.wake_r:
                    while True:
                        try:
                            if not os.read(self.wake_r, 4096):
                                break
                        except BlockingIOError:
                            break
                elif fd == self.control.fileno():
                    if not self._accept(poller, by_fd):
                        self._kill_all()
                        return 0
                else:  # a grader's connection: closed (or talking out of turn)
                    pid = by_fd.pop(fd, None)
                    poller.unregister(fd)
                    if pid is not None:
                        self._kill(pid)
            for pid in self._reap():
                conn = self.conns.pop(pid)
                by_fd.pop(conn.fileno(), None)
                try:
                    poller.unregister(conn)
                except KeyError:
                    pass
                conn.close()

    def _accept(self, poller: select.poll, by_fd: dict[int, int]) -> bool:
        """Fork a worker for one request; False when every grader has gone."""
        try:
            data, fds, _, _ = socket.recv_fds(self.control, MAX_REQUEST_BYTES, 8)
        except (BlockingIOError, InterruptedError):
            return True
        if not data and not fds:
            return False
        if len(fds) != (4 if self.role == "worker" else 2):
            for fd in fds:
                os.close(fd)
            return True
        conn = socket.socket(fileno=fds[0])
        pipes = fds[1:]
        try:
            request = json.loads(data)
            if _threads() != 1:
                raise ZygoteError(f"the zygote has {_threads()} threads; it only forks with one")
            sys.stdout.flush()
            sys.stderr.flush()
            pid = os.fork()
        except Exception as exc:  # noqa: BLE001 - reported to the grader, which starts it cold
            _say(conn, {"error": f"{type(exc).__name__}: {exc}"})
            conn.close()
            for fd in pipes:
                os.close(fd)
            return True
        if pid == 0:  # pragma: no cover - the child; covered by the worker tests
            code = 70
            try:
                self._detach()
                if self.role == "worker":
                    code = self._become_worker(request, pipes)
                else:
                    code = self._become_grader(request, pipes[0])
            except BaseException:  # noqa: BLE001 - the grader reports the exit status
                import traceback

                traceback.print_exc()
            finally:
                os._exit(code)
        for fd in pipes:
            os.close(fd)
        self.served += 1
        self.conns[pid] = conn
        by_fd[conn.fileno()] = pid
        poller.register(conn, select.POLLIN | select.POLLHUP)
        _say(conn, {"pid": pid})
        return True

    def _detach(self) -> None:  # pragma: no cover - in the forked child
        signal.set_wakeup_fd(-1)
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        os.setsid()  # its own session and process group, killed as a group

    def _become_worker(self, request: dict, pipes: list[int]) -> int:  # pragma: no cover
        """In the forked child: run the worker as if started cold (it isolates itself)."""
        request_fd, response_fd, output_fd = pipes
        _redirect(output_fd, keep={request_fd, response_fd})
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        import tempfile

        tempfile.tempdir = None  # found again from TMPDIR, the worker's own directory
        import numpy

        numpy.random.seed()  # noqa: NPY002 - the legacy global state students use, not the zygote's
        from robolab.grading import worker

        config = {"request_fd": request_fd, "response_fd": response_fd, "plan": request["plan"]}
        return worker.main(["robolab.grading.worker", json.dumps(config)])

    def _become_grader(self, request: dict, log_fd: int) -> int:  # pragma: no cover
        """In the forked child: ``python -m pytest ARGS`` in ``cwd``, output to the log."""
        keep = {int(fd) for fd in request.get("keep", ())}
        _redirect(log_fd, keep=keep)
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        sys.path[0] = request["cwd"]  # what `python -m pytest` run there would have
        sys.argv = ["pytest", *request["args"]]
        import pytest

        code = int(pytest.main(request["args"]))
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        return code

    def _kill(self, pid: int) -> None:
        """SIGKILL a child's process group and, for a worker of root, every process of its uid."""
        try:
            os.killpg(pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        if self.role == "worker" and os.geteuid() == 0:
            from robolab.grading import sandbox
            from robolab.grading.proxy import _kill_uid

            _kill_uid(sandbox.worker_uid(pid))

    def _reap(self) -> list[int]:
        reaped = []
        while True:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                break
            if pid == 0:
                break
            if pid in self.conns:
                _say(self.conns[pid], {"exit": os.waitstatus_to_exitcode(status)})
                reaped.append(pid)
        return reaped

    def _kill_all(self) -> None:
        for pid in list(self.conns):
            self._kill(pid)
        deadline = time.monotonic() + 10
        while self.conns and time.monotonic() < deadline:
            for pid in self._reap():
                self.conns.pop(pid).close()
            time.sleep(0.01)


def _redirect(output_fd: int, keep: set[int]) -> None:  # pragma: no cover - in the child
    """stdin from /dev/null, stdout and stderr to ``output_fd``; close every other descriptor."""
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.dup2(output_fd, 1)
    os.dup2(output_fd, 2)
    keep = {0, 1, 2, *keep}
    for name in os.listdir("/proc/self/fd"):
        fd = int(name)
        if fd not in keep:
            try:
                os.close(fd)
            except OSError:
                pass  # the listing's own descriptor, already gone


def _say(conn: socket.socket, message: dict) -> None:
    try:
        conn.sendall(json.dumps(message).encode() + b"\n")
    except OSError:
        pass  # the grader has gone; its worker is killed when the connection is seen closed


def main(argv: list[str] | None = None) -> int:
    """Run the zygote: preload, then fork a worker per request until every grader has gone."""
    argv = sys.argv if argv is None else argv
    config = json.loads(argv[1])
    control = socket.socket(fileno=config["control_fd"])
    os.set_inheritable(control.fileno(), False)
    role = config.get("role", "worker")
    try:
        _preload(role)
    except Exception as exc:  # noqa: BLE001 - the grader starts workers cold instead
        print(f"robolab zygote: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 3
    return _Server(control, role).run()


# --- the grader's side -------------------------------------------------------------------------


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
        with self._lock:
            if self.returncode is not None:
                return
            if not _readable(self.conn, timeout):
                return
            chunk = self.conn.recv(4096)
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
        if control_fd is not None:
            self.control = socket.socket(fileno=control_fd)
            if self.control.type != socket.SOCK_SEQPACKET:
                self.control.detach()
                raise ZygoteError(f"descriptor {control_fd} is not a zygote's control socket")
            os.set_inheritable(control_fd, False)
            return
        self.control, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        import subprocess

        config = json.dumps({"control_fd": theirs.fileno(), "role": role})
        if role == "worker":  # exactly like a cold worker: isolated mode, minimal environment
            argv = [sys.executable, "-I", "-B", "-m", "robolab.grading.zygote", config]
            env, cwd = _zygote_env(), "/"
        else:
            argv = [sys.executable, "-m", "robolab.grading.zygote", config]
            env = dict(os.environ if env is None else env)
            for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
                env.setdefault(name, "1")  # single-threaded, or it could not fork safely
        try:
            self.process = subprocess.Popen(
                argv,
                stdin=subprocess.DEVNULL,
                pass_fds=(theirs.fileno(), *pass_fds),
                env=env,
                cwd=cwd,
                start_new_session=True,  # a Ctrl-C in the grader's terminal reaches the grader only
            )
        finally:
            theirs.close()
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


if __name__ == "__main__":
    sys.exit(main())
