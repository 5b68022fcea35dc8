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
from typing import Any

__all__ = ["PRELOAD", "WarmChild", "Zygote", "ZygoteError", "shared"]

#: Modules imported once by the zygote: what the worker and the labs' notebooks import.
PRELOAD = (
    "numpy",
    "matplotlib",
    "matplotlib.pyplot",
    "scipy.special",
    "scipy.ndimage",
    "scipy.integrate",
    "scipy.stats",
    "robolab.grading.codec",
    "robolab.geometry",
    "robolab.validation",
    "robolab.maps",
    "robolab.raycast",
    "robolab.plotting",
    "robolab.checks",
)
#: Environment variable naming an inherited control socket (set by the runner for pytest).
FD_VARIABLE = "ROBOLAB_WARM_FD"
#: Set to "0" to start every worker cold (``python -m robolab.grading.worker``).
SWITCH_VARIABLE = "ROBOLAB_WARM_WORKERS"
#: Seconds the zygote may take to import :data:`PRELOAD` and say it is ready.
STARTUP_SECONDS = 60.0
#: Largest request (JSON) accepted by the zygote.
MAX_REQUEST_BYTES = 1 << 20


class ZygoteError(RuntimeError):
    """The zygote could not be started or did not fork a worker."""


# --- the zygote process ------------------------------------------------------------------------


def _preload() -> None:
    from robolab.grading.worker import RefuseAnswers

    sys.meta_path.insert(0, RefuseAnswers())  # the answers can never be in a child's memory
    import matplotlib

    matplotlib.use("Agg")
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)


def _threads() -> int:
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return threading.active_count()


class _Server:
    """The zygote's loop: fork a worker per request, report its exit, kill orphans."""

    def __init__(self, control: socket.socket) -> None:
        self.control = control
        self.conns: dict[int, socket.socket] = {}  # worker pid -> its grader's connection
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
        while True:
            try:
                events = poller.poll(1000)
            except InterruptedError:  # pragma: no cover - poll retries on EINTR since 3.5
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
                        _kill_worker(pid)
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
        if len(fds) != 4:
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
                code = self._become_worker(request, pipes)
            except BaseException:  # noqa: BLE001 - the grader reports the exit status
                import traceback

                traceback.print_exc()
            finally:
                os._exit(code)
        for fd in pipes:
            os.close(fd)
        self.conns[pid] = conn
        by_fd[conn.fileno()] = pid
        poller.register(conn, select.POLLIN | select.POLLHUP)
        _say(conn, {"pid": pid})
        return True

    def _become_worker(self, request: dict, pipes: list[int]) -> int:  # pragma: no cover
        """In the forked child: detach from the zygote, then run the worker as if started cold."""
        signal.set_wakeup_fd(-1)
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        os.setsid()  # its own session and process group, killed as a group
        request_fd, response_fd, output_fd = pipes
        devnull = os.open(os.devnull, os.O_RDONLY)
        os.dup2(devnull, 0)
        os.dup2(output_fd, 1)
        os.dup2(output_fd, 2)
        keep = {0, 1, 2, request_fd, response_fd}
        for name in os.listdir("/proc/self/fd") if os.path.isdir("/proc/self/fd") else ():
            fd = int(name)
            if fd not in keep:
                try:
                    os.close(fd)
                except OSError:
                    pass  # the directory's own descriptor, already gone
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        import tempfile

        tempfile.tempdir = None  # found again from TMPDIR, the worker's own directory
        import numpy

        numpy.random.seed()  # not the zygote's state: every child draws its own
        from robolab.grading import worker

        config = {"request_fd": request_fd, "response_fd": response_fd, "plan": request["plan"]}
        return worker.main(["robolab.grading.worker", json.dumps(config)])

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
            _kill_worker(pid)
        deadline = time.monotonic() + 10
        while self.conns and time.monotonic() < deadline:
            for pid in self._reap():
                self.conns.pop(pid).close()
            time.sleep(0.01)


def _kill_worker(pid: int) -> None:
    """SIGKILL a worker's process group and, as root, every process of its uid."""
    from robolab.grading import sandbox

    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    if os.geteuid() == 0:
        from robolab.grading.proxy import _kill_uid

        _kill_uid(sandbox.worker_uid(pid))


def _say(conn: socket.socket, message: dict) -> None:
    try:
        conn.sendall(json.dumps(message).encode() + b"\n")
    except OSError:
        pass  # the grader has gone; its worker is killed when the connection is seen closed


def main(argv: list[str] | None = None) -> int:
    """Run the zygote: preload, say ready on the control socket, then serve forks."""
    argv = sys.argv if argv is None else argv
    config = json.loads(argv[1])
    control = socket.socket(fileno=config["control_fd"])
    os.set_inheritable(control.fileno(), False)
    try:
        _preload()
    except Exception as exc:  # noqa: BLE001 - the grader starts workers cold instead
        control.send(json.dumps({"error": f"{type(exc).__name__}: {exc}"}).encode())
        return 3
    control.send(json.dumps({"ready": os.getpid()}).encode())
    return _Server(control).run()


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
    """

    def __init__(self, control_fd: int | None = None) -> None:
        self.process = None
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

        config = {"control_fd": theirs.fileno()}
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-I", "-B", "-m", "robolab.grading.zygote", json.dumps(config)],
                stdin=subprocess.DEVNULL,
                pass_fds=(theirs.fileno(),),
                env=_zygote_env(),
                cwd="/",
                start_new_session=True,  # a Ctrl-C in the grader's terminal reaches the grader only
            )
        finally:
            theirs.close()
        ready = _readable(self.control, STARTUP_SECONDS)
        answer = json.loads(self.control.recv(MAX_REQUEST_BYTES) or b"{}") if ready else {}
        if "ready" not in answer:
            self.close()
            raise ZygoteError(f"the zygote did not start: {answer.get('error', 'no answer')}")
        self.pid = int(answer["ready"])

    def fileno(self) -> int:
        """The control socket, to pass to a grading process (with :data:`FD_VARIABLE`)."""
        return self.control.fileno()

    def spawn(self, plan: dict, env: dict[str, str], cwd: str, pipes: tuple[int, int, int]):
        """Fork a worker: ``pipes`` = (request read end, response write end, output write end).

        The caller keeps (and closes) its copies of the pipes.

        Returns
        -------
        WarmChild
            The worker, running :func:`robolab.grading.worker.main`.

        Raises
        ------
        ZygoteError
            When the zygote is gone or refuses.
        """
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            request = json.dumps({"plan": plan, "env": env, "cwd": cwd}).encode()
            with self._lock:
                socket.send_fds(self.control, [request], [theirs.fileno(), *pipes])
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
                raise ZygoteError("the zygote did not fork a worker")
            buffer += chunk
        line, rest = buffer.split(b"\n", 1)
        answer = json.loads(line)
        if "pid" not in answer:
            ours.close()
            raise ZygoteError(f"the zygote did not fork a worker: {answer.get('error')}")
        return WarmChild(ours, int(answer["pid"]), rest)

    def close(self) -> None:
        """Close this handle; a zygote this process started exits (killing its workers)."""
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
_shared_lock = threading.Lock()


def shared() -> Zygote | None:
    """This process's zygote: the inherited one, else one started on first use; None if off.

    Off when :data:`SWITCH_VARIABLE` is ``"0"``, when fork is unavailable, or
    after a zygote failed to start (a warning says why; workers then start cold).
    """
    global _shared, _shared_failed
    if os.environ.get(SWITCH_VARIABLE) == "0" or not hasattr(os, "fork"):
        return None
    if not hasattr(socket, "send_fds") or sys.platform != "linux":
        return None
    with _shared_lock:
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
            import warnings

            warnings.warn(f"robolab grading: workers start cold: {exc}", stacklevel=2)
            return None
        import atexit

        atexit.register(_shared.close)
        return _shared


def reset_shared(zygote: Any = None) -> None:
    """Forget this process's zygote (closing it) and use ``zygote`` next (tests, benchmarks)."""
    global _shared, _shared_failed
    with _shared_lock:
        if _shared is not None and _shared is not zygote:
            _shared.close()
        _shared, _shared_failed = zygote, None


if __name__ == "__main__":
    sys.exit(main())
