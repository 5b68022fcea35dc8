"""The zygote: a clean process that imports the libraries once and forks workers (or pytest runs).

Starting a worker cold costs an interpreter start, numpy, and then whatever the
notebook imports (``matplotlib.pyplot``, ``robolab.plotting``, scipy): most of
the time it takes to grade a small lab. The *zygote* pays that once. It is
started exactly like a worker (``python -I -B -m robolab.grading.isolation.zygote``, a
minimal environment, no current directory on ``sys.path``), imports
:data:`PRELOAD`, and then, for each worker the grader asks for, forks a child
that becomes the worker: it gets its own session, its pipes, working directory
and environment, and runs :func:`robolab.grading.isolation.worker.main`, which isolates
it (:func:`robolab.grading.isolation.sandbox.apply`: namespaces, view, uid, limits,
Landlock) before any student code exists in it -- the same code path as a cold
worker, so isolation is unchanged. Started with the role ``"grader"`` (by
:func:`robolab.grading.isolation.warm.shared_grader`, in the project root, with the
grader's environment) it imports pytest and numpy instead and forks one pytest
run of the hidden tests per request: the trusted side, which may see the answers.
The grader's handle on a zygote is :mod:`robolab.grading.isolation.warm`.

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
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time

__all__ = ["GRADER_PRELOAD", "GRADER_PRELOAD_IDLE", "PRELOAD", "PRELOAD_IDLE", "main"]

#: Modules the zygote imports before it forks the first worker: what every lab's notebook uses.
PRELOAD = (
    "numpy",
    "numpy.random",  # imported lazily by numpy 2; every child reseeds it
    "matplotlib",
    "matplotlib.pyplot",
    "fractions",
    # the worker's own modules (what a forked child imports before it serves a call)
    "robolab.grading.isolation.worker",
    "robolab.grading.isolation.sandbox",
    "robolab.grading.loading.kernel",
    "robolab.grading.loading.delegation",
    "robolab.grading.wire.observe",
    "robolab.grading.wire.depcall",
    "robolab.grading.wire.arrays",
    "robolab.grading.wire.codec",
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
#: Requests served before the idle imports start (a batch, not one submission). A request
#: marked ``"probe"`` (:mod:`~.isolation.protection`) does not count: while one submission
#: is graded the idle imports would take a core from its pytest run and worker.
IDLE_AFTER = 2
#: What the grader zygote (the trusted side: pytest, the hidden tests) imports before forking.
GRADER_PRELOAD = (
    "numpy",
    "numpy.random",  # numpy 2 imports these two lazily; every hidden test uses them
    "numpy.testing",
    "pytest",
    "_pytest.python",
    "_pytest.fixtures",
    "_pytest.assertion.rewrite",
    # pytest's default plugins (imported by every run's configuration) and what they import
    *(
        f"_pytest.{name}"
        for name in (
            "junitxml pastebin helpconfig faulthandler skipping unittest warnings setuponly "
            "setupplan tracemalloc threadexception unraisableexception _argcomplete"
        ).split()
    ),
    "pdb",
    "tomllib",
    "xml.etree.ElementTree",
    "concurrent.futures",
    "fractions",
    "robolab.validation",
    "robolab.grading.running.proxy",
    "robolab.grading.running.pytest_plugin",
    # what every run's lab fixture imports (issue 29)
    "robolab.grading.running.answers",
    "robolab.grading.isolation.warm",
    "robolab.grading.wire.depcall",
    "encodings.ascii",
)
#: ... and while it is idle: what the hidden tests and reference solutions import.
GRADER_PRELOAD_IDLE = (
    "scipy.special",
    "scipy.ndimage",
    "scipy.integrate",
    "scipy.stats",
    "robolab.maps",
    "robolab.raycast",
    # numba and the ray-casting kernels the hidden tests of the beam-model and MCL labs
    # call, and MCL's fused likelihood-field sum (import and load from numba's cache:
    # 1.5 s of every such pytest run otherwise);
    # only once a run of such a lab was asked for (COMPILED_LABS)
    "robolab.grading.isolation.zygote:_warm_compiled",
    "robolab.bag",
    "robolab.world",
    "robolab.fiducials",
    "filterpy.kalman",
)
#: The idle step that loads numba's kernels, and the hidden-test modules whose pytest runs
#: cast rays in the grader (the step waits until a run of one of them was asked for).
WARM_COMPILED = "robolab.grading.isolation.zygote:_warm_compiled"
COMPILED_LABS = ("test_beam_model.py", "test_mcl.py")
#: Largest request (JSON) accepted by the zygote.
MAX_REQUEST_BYTES = 1 << 20


# --- the zygote process ------------------------------------------------------------------------


def _preload(role: str) -> None:
    if role == "worker":
        from robolab.grading.isolation.worker import RefuseAnswers

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
    """Import module ``name``; ``"module:function"`` imports it and calls the function."""
    import importlib

    name, _, function = name.partition(":")
    try:
        module = importlib.import_module(name)
    except ImportError:
        return  # an optional library that is not installed: the worker reports it if used
    if function:
        getattr(module, function)()


def _warm_compiled() -> None:
    """Load numba's compiled kernels (the grader zygote, while idle): ray casting, and the
    fused likelihood-field sum of lab 05's reference (``robolab.fieldsum``), which answers
    the depcalls of an MCL submission whose models fail their tests (1.5-2 s of every such
    pytest run otherwise)."""
    try:
        import numpy as np

        from robolab import fieldsum
        from robolab.maps import OccupancyGrid
        from robolab.raycast import cast_rays

        grid = OccupancyGrid(np.zeros((4, 4)), 0.1, (0.0, 0.0, 0.0))
        cast_rays(grid, np.full((1, 3), 0.2), np.zeros(1), 1.0)
        fieldsum._fused()
    except Exception:  # noqa: BLE001 - no numba, or it failed: each run loads its own
        pass


def _keep_rewritten_tests(folder: str) -> None:  # pragma: no cover - in a forked pytest run
    """Keep the hidden tests as pytest rewrote their asserts in ``folder``, for the next runs.

    pytest caches a rewritten test module as a ``.pyc`` beside it, unless bytecode is not
    written (``PYTHONDONTWRITEBYTECODE``, which a pytest run of the grader sets: nothing is
    written into the course's folders). Then every run rewrites the lab's hidden tests
    again: a tenth of a second of a small lab's grading. Here the cache is ``folder``
    (private to the grader zygote, mode 0700, removed when it exits; workers fork from
    the other zygote and never see it), and only the rewritten tests are written there:
    the first run of a lab writes them, the next ones read them (pytest checks the
    source's hash). With a pytest whose internals differ, runs rewrite as before.
    """
    try:
        from _pytest.assertion import rewrite
    except ImportError:
        return
    needed = ("get_cache_dir", "_rewrite_test", "_write_pyc", "try_makedirs", "PYC_TAIL")
    if not all(hasattr(rewrite, name) for name in needed):
        return
    from pathlib import Path

    def cache_dir(path: Path) -> Path:
        return Path(folder, *Path(path).parts[1:-1])

    rewrite_test = rewrite._rewrite_test

    def rewrite_and_keep(path: Path, config):
        source, code = rewrite_test(path, config)
        directory = cache_dir(path)
        if rewrite.try_makedirs(directory):
            pyc = directory / (Path(path).name[:-3] + rewrite.PYC_TAIL)
            rewrite._write_pyc(config.stash[rewrite.assertstate_key], code, source, pyc)
        return source, code

    rewrite.get_cache_dir, rewrite._rewrite_test = cache_dir, rewrite_and_keep


def _entry_point_names() -> frozenset[str] | None:
    """The names of the installed ``pytest11`` entry points (None when they cannot be read)."""
    try:
        from importlib.metadata import entry_points

        return frozenset(ep.name for ep in entry_points(group="pytest11"))
    except Exception:  # noqa: BLE001 - runs look them up themselves, as before
        return None


def _skip_needless_pytest_work(names: frozenset[str] | None) -> None:  # pragma: no cover
    """Spare a forked pytest run two scans whose answer is known (issue 29).

    - ``-p MODULE`` makes pytest read every installed distribution's entry points for one
      named ``MODULE`` (2 % of a Bayes run's CPU); the zygote read their names once
      (``names``), so a name that is none of them is answered at once, as the scan would.
    - pytest 9 looks behind every attribute of every plugin, conftest and test module for a
      fixture hidden under decorators, only to *warn* about it (6 % of a run, most of it in
      pytest's own plugins). A grading run shows no warnings (``-q``, its log is read only
      when it fails), and the instructor's own pytest run of the hidden tests still warns.
    Both are patched on this child's copy of pytest only; a pytest without these internals
    runs as it is.
    """
    from _pytest.config import PytestPluginManager
    from _pytest.fixtures import FixtureManager

    if names is not None and hasattr(PytestPluginManager, "load_setuptools_entrypoints"):
        load = PytestPluginManager.load_setuptools_entrypoints

        def load_known(self, group: str, name: str | None = None) -> int:
            if group == "pytest11" and name is not None and name not in names:
                return 0
            return load(self, group, name)

        PytestPluginManager.load_setuptools_entrypoints = load_known
    if hasattr(FixtureManager, "_check_for_wrapped_fixture"):
        FixtureManager._check_for_wrapped_fixture = lambda self, name, obj: None


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
        #: The grader zygote's folder of hidden tests as pytest rewrote their asserts (a
        #: private temporary one, gone when it exits; see _keep_rewritten_tests).
        self.pycache = tempfile.mkdtemp(prefix="robolab-grader-pyc-") if role == "grader" else None
        self.conns: dict[int, socket.socket] = {}  # worker pid -> its grader's connection
        self.wants_compiled = False  # a pytest run of a COMPILED_LABS lab was asked for
        self.deferred: list[str] = []  # idle imports waiting for such a run
        self.served = 0
        #: Names of the installed pytest plugins' entry points (group ``pytest11``), read once.
        self.entry_point_names = _entry_point_names() if role == "grader" else None
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
                name = idle.pop(0)
                if name == WARM_COMPILED and not self.wants_compiled:
                    self.deferred.append(name)  # a batch without those labs never pays it
                    continue
                _import(name)
                _freeze()
                continue
            if self.wants_compiled and self.deferred:
                idle += self.deferred
                self.deferred.clear()
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
            if self.role == "grader" and not self.wants_compiled:
                args = request.get("args") or ()
                self.wants_compiled = any(str(a).endswith(COMPILED_LABS) for a in args)
            if _threads() != 1:
                raise RuntimeError(f"the zygote has {_threads()} threads; it only forks with one")
            sys.stdout.flush()
            sys.stderr.flush()
            detached_r, detached_w = os.pipe()
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
                os.close(detached_r)
                self._detach()
                os.close(detached_w)  # the grader may signal its process group from now on
                if self.role == "worker":
                    code = self._become_worker(request, pipes)
                else:
                    code = self._become_grader(request, pipes[0])
            except KeyboardInterrupt:  # stopped by its grader (SIGINT) while starting
                code = 130
            except BaseException:  # noqa: BLE001 - the grader reports the exit status
                import traceback

                traceback.print_exc()
            finally:
                os._exit(code)
        for fd in pipes:
            os.close(fd)
        # The pid is told once the child leads its own process group (or has died): the
        # grader stops a child by signalling that group, which must exist by then.
        os.close(detached_w)
        try:
            os.read(detached_r, 1)
        finally:
            os.close(detached_r)
        if not request.get("probe"):  # the protection probe is not a submission of a batch
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
        from robolab.grading.isolation import worker

        config = {"request_fd": request_fd, "response_fd": response_fd, "plan": request["plan"]}
        return worker.main(["robolab.grading.isolation.worker", json.dumps(config)])

    def _become_grader(self, request: dict, log_fd: int) -> int:  # pragma: no cover
        """In the forked child: ``python -m pytest ARGS`` in ``cwd``, output to the log.

        A request ``{"task": "probe", "out": PATH, ...}`` instead probes what this
        machine's workers are protected from (:func:`~.protection.probe_protection`,
        with a worker of the worker zygote) and writes the result to ``PATH`` as JSON.
        """
        keep = {int(fd) for fd in request.get("keep", ())}
        _redirect(log_fd, keep=keep)
        # Ctrl-C semantics whatever the zygote inherited (a grader started with SIGINT
        # ignored): the grader stops a run with SIGINT so that its fixtures close the worker.
        signal.signal(signal.SIGINT, signal.default_int_handler)
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        sys.path[0] = request["cwd"]  # what `python -m pytest` run there would have
        if request.get("task") == "probe":
            from robolab.grading.isolation import protection

            found = protection.probe_protection()
            with open(request["out"], "w", encoding="utf-8") as f:
                json.dump(found.to_dict(), f)
            return 0
        sys.argv = ["pytest", *request["args"]]
        import pytest

        if self.pycache is not None:
            _keep_rewritten_tests(self.pycache)
        _skip_needless_pytest_work(self.entry_point_names)

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
            from robolab.grading.isolation import sandbox
            from robolab.grading.running.channel import kill_uid

            kill_uid(sandbox.worker_uid(pid))

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
    if config.get("ready_fd") is not None:
        os.set_inheritable(config["ready_fd"], False)
    role = config.get("role", "worker")
    try:
        _preload(role)
    except Exception as exc:  # noqa: BLE001 - the grader starts workers cold instead
        print(f"robolab zygote: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 3
    ready = config.get("ready_fd")
    if ready is not None:  # the grader may no longer just kill it: it may fork from now on
        try:
            os.write(ready, b"r")
        except BrokenPipeError:  # the grader has gone (or stopped) before it was ready
            return 0
        finally:
            os.close(ready)
    server = _Server(control, role)
    try:
        code = server.run()
    finally:
        if server.pycache is not None:
            shutil.rmtree(server.pycache, ignore_errors=True)
    # Every child is reaped and nothing is kept: exit without tearing down numpy, matplotlib
    # and pytest module by module (a tenth of a second the grader would wait for).
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    sys.exit(main())
