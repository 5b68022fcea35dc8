"""What the OS lets a worker do: read the runtime, not the answers; no network; few processes.

These tests run real workers on this machine. They need Linux with Landlock
(or root for namespaces); elsewhere the isolation tests skip and the warning
test still runs.
"""

from __future__ import annotations

import dataclasses
import os
import socket
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

import robolab
from robolab.grading.isolation import processes, sandbox
from robolab.grading.running import proxy as proxy_module
from robolab.grading.running.proxy import (
    IsolationWarning,
    StudentCodeError,
    WorkerTimeout,
    open_submission,
)
from tests.grading import TEST_LIMITS, write_notebook

REPOSITORY = Path(robolab.__file__).resolve().parent.parent
ISOLATED = sandbox.landlock_abi() > 0 or os.geteuid() == 0
needs_isolation = pytest.mark.skipif(not ISOLATED, reason="needs Landlock or root on Linux")

PROBES = """
import os
import resource
import signal
import socket
import sys
import time

def read(path):
    with open(path, "rb") as f:
        return f.read(64)

def listdir(path):
    return sorted(os.listdir(path))

def connect(port):
    with socket.create_connection(("127.0.0.1", port), timeout=2):
        return True

def import_everything():
    import numpy
    import scipy.stats
    import filterpy.kalman
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import robolab.maps
    fig = plt.figure()
    plt.plot([1, 2, 3])
    fig.savefig("figure.png")
    return os.path.getsize("figure.png"), float(scipy.stats.norm.pdf(0.0))

def identity():
    return os.getuid(), os.getgid(), os.getgroups(), os.getcwd()

def become_root():
    os.setuid(0)

def raise_process_limit():
    resource.setrlimit(resource.RLIMIT_NPROC, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))

def signal_grader():
    os.kill(os.getppid(), 0)  # a permission check only: signal 0 is never delivered

def fork_children(n, detach):
    pids = []
    for _ in range(n):
        try:
            pid = os.fork()
        except BlockingIOError:
            break
        if pid == 0:
            if detach:
                try:
                    os.setsid()  # would leave the worker's process group
                except OSError:
                    pass
            time.sleep(120)
            os._exit(0)
        pids.append(pid)
    return pids

def daemon():
    # The classic double fork: the grandchild is orphaned, and tries to leave the group.
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        try:
            os.setsid()
            detached = 1
        except OSError:
            detached = 0
        grandchild = os.fork()
        if grandchild == 0:
            time.sleep(120)
            os._exit(0)
        os.write(w, b"%d %d" % (grandchild, detached))
        os._exit(0)
    os.waitpid(pid, 0)
    grandchild, detached = os.read(r, 100).split()
    return int(grandchild), bool(int(detached))

def spin(seconds):
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass

def burn_in_children(n, seconds, wait):
    pids = []
    for _ in range(n):
        pid = os.fork()
        if pid == 0:
            spin(seconds)
            os._exit(0)
        pids.append(pid)
    if wait:
        for pid in pids:
            os.waitpid(pid, 0)
    return pids
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


@pytest.fixture(scope="module")
def probes(tmp_path_factory):
    path = write_notebook(tmp_path_factory.mktemp("sandbox") / "probes.ipynb", PROBES)
    # A longer wall limit: importing scipy.stats and matplotlib takes seconds on a busy machine.
    with open_submission(
        path, limits=dataclasses.replace(TEST_LIMITS, wall_seconds=30, cpu_seconds=20)
    ) as sub:
        yield sub


@pytest.fixture(scope="module")
def secret():
    """A world-readable file outside every allowed path: only the sandbox hides it."""
    folder = Path(tempfile.mkdtemp(prefix="robolab-secret-"))
    folder.chmod(0o755)
    path = folder / "answers.py"
    path.write_text("ANSWER = 42\n")
    path.chmod(0o644)
    yield path
    path.unlink()
    folder.rmdir()


@pytest.fixture
def landlock_only(monkeypatch):
    """Workers isolated by Landlock alone (no namespaces, same uid): an unprivileged grader."""
    if sandbox.landlock_abi() == 0:
        pytest.skip("needs Landlock")
    original = sandbox.plan_sandbox

    def plan(*args, **kwargs):
        return dataclasses.replace(original(*args, **kwargs), view_root=None, drop_privileges=False)

    monkeypatch.setattr(sandbox, "plan_sandbox", plan)


@pytest.fixture
def listener():
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    server.setblocking(False)
    yield server
    server.close()


def _assert_no_connection(server: socket.socket) -> None:
    with pytest.raises(BlockingIOError):
        server.accept()


def test_this_machine_isolates():
    # The CI machine (Linux 6.x, root) must isolate; a laptop without Landlock skips the rest.
    if os.uname().release.startswith("6."):
        assert sandbox.landlock_abi() >= 4


@needs_isolation
def test_report(probes):
    report = probes.sandbox
    assert report.protects_answers
    assert report.network_denied != "no"
    if os.geteuid() == 0:
        assert report.view and report.network_denied == "namespace"
        assert report.uid >= sandbox.UID_BASE and report.process_limit


@needs_isolation
def test_the_runtime_is_usable(probes):
    size, density = probes.import_everything()
    assert size > 1000
    assert density == pytest.approx(1 / np.sqrt(2 * np.pi))
    assert probes.read(robolab.__file__) == Path(robolab.__file__).read_bytes()[:64]
    assert probes.listdir(str(robolab.DATA_DIR)) == sorted(os.listdir(robolab.DATA_DIR))


@needs_isolation
@pytest.mark.parametrize(
    "path",
    [
        REPOSITORY / "solutions" / "demo.py",
        REPOSITORY / "solutions" / "__init__.py",
        REPOSITORY / "tests" / "labs" / "test_demo.py",
        REPOSITORY / "tests" / "conftest.py",
        REPOSITORY / "pyproject.toml",
        Path("/etc/passwd"),
        Path("/proc/1/environ"),
    ],
)
def test_the_answers_are_unreadable(probes, path):
    assert path.exists(), "the probe must target a file that exists"
    with pytest.raises(StudentCodeError) as info:
        probes.read(str(path))
    assert isinstance(info.value, OSError)


@needs_isolation
def test_other_files_are_unreadable(probes, secret):
    with pytest.raises(OSError):
        probes.read(str(secret))
    with pytest.raises(OSError):
        probes.listdir(str(REPOSITORY / "solutions"))


@needs_isolation
def test_no_network(probes, listener):
    with pytest.raises(StudentCodeError) as info:
        probes.connect(listener.getsockname()[1])
    assert isinstance(info.value, OSError)
    _assert_no_connection(listener)


@needs_isolation
def test_privileges_cannot_be_regained(probes):
    uid, gid, groups, cwd = probes.identity()
    if os.geteuid() == 0:
        assert uid != 0 and gid != 0 and groups == []
        with pytest.raises(PermissionError):
            probes.become_root()
    with pytest.raises(StudentCodeError):
        probes.raise_process_limit()
    with pytest.raises(PermissionError):
        probes.signal_grader()


def _all_dead(pids: list[int]) -> bool:
    deadline = time.monotonic() + 60  # only catches a process that never dies
    while any(_alive(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not [pid for pid in pids if _alive(pid)]


@needs_isolation
@pytest.mark.skipif(
    os.geteuid() != 0, reason="the process limit of an unprivileged grader is the grader's own"
)
def test_process_limit_holds_and_nothing_outlives_its_call(tmp_path):
    # A bounded fork loop: 3x the limit of children that sleep; some try to detach with setsid.
    path = write_notebook(tmp_path / "fork.ipynb", PROBES)
    with open_submission(path, limits=TEST_LIMITS) as sub:
        attached = sub.fork_children(3 * TEST_LIMITS.max_processes, False)
        assert _all_dead(attached), "children a call started must die when it returns"
        detached = sub.fork_children(3 * TEST_LIMITS.max_processes, True)
        assert 0 < len(attached) < TEST_LIMITS.max_processes
        assert 0 < len(detached) < TEST_LIMITS.max_processes
        assert _all_dead(detached)
        assert sub.identity()[0] == sub.sandbox.uid  # the worker itself lives on


@needs_isolation
def test_a_double_forked_daemon_neither_detaches_nor_survives(probes):
    grandchild, detached = probes.daemon()
    assert not detached, "setsid must fail: the process group holds everything"
    assert _all_dead([grandchild])
    worker = probes._worker
    left = [m for m in processes.group_members(worker.process.pid) if m.state != "Z"]
    assert [m.pid for m in left] == [worker.process.pid]


@needs_isolation
def test_cpu_of_children_counts_against_the_call(tmp_path):
    path = write_notebook(tmp_path / "burn.ipynb", PROBES)
    limits = dataclasses.replace(TEST_LIMITS, cpu_seconds=1, wall_seconds=20)
    with open_submission(path, limits=limits) as sub:
        # Two children burn 2 s of CPU each while the worker itself only waits.
        with pytest.raises(WorkerTimeout, match="CPU") as info:
            sub.burn_in_children(2, 2.0, True)
        assert "processes it started" in str(info.value)
        # Children left burning when the call returns are killed (and charged).
        pids = sub.burn_in_children(2, 30.0, False)
        assert _all_dead(pids)
        # Waiting for a child that uses little CPU is fine.
        assert len(sub.burn_in_children(1, 0.05, True)) == 1


@pytest.mark.filterwarnings("ignore::robolab.grading.running.proxy.IsolationWarning")
def test_landlock_alone_protects_the_answers(landlock_only, tmp_path, listener, secret):
    path = write_notebook(tmp_path / "ll.ipynb", PROBES)
    with open_submission(
        path, limits=dataclasses.replace(TEST_LIMITS, wall_seconds=30, cpu_seconds=20)
    ) as sub:
        assert sub.sandbox.landlock and not sub.sandbox.view
        assert sub.import_everything()[0] > 1000
        for target in (
            REPOSITORY / "solutions" / "demo.py",
            REPOSITORY / "tests" / "conftest.py",
            secret,
        ):
            with pytest.raises(PermissionError):
                sub.read(str(target))
        with pytest.raises(PermissionError):
            sub.connect(listener.getsockname()[1])
        _assert_no_connection(listener)
        with pytest.raises(PermissionError):
            sub.signal_grader()  # Landlock's signal scope (ABI 6) holds even for the same uid


@pytest.mark.filterwarnings("ignore::robolab.grading.running.proxy.IsolationWarning")
def test_without_isolation_grading_goes_on_with_a_warning(monkeypatch, tmp_path, capsys):
    original = sandbox.plan_sandbox

    def plan(*args, **kwargs):
        return dataclasses.replace(
            original(*args, **kwargs), view_root=None, drop_privileges=False, landlock=False
        )

    monkeypatch.setattr(sandbox, "plan_sandbox", plan)
    monkeypatch.setattr(proxy_module, "_warned", set())
    path = write_notebook(tmp_path / "open.ipynb", "def f():\n    return 1")
    with pytest.warns(IsolationWarning, match="could read the reference solutions"):
        sub = open_submission(path, limits=TEST_LIMITS)
    with sub:
        assert sub.f() == 1
    assert "could read the reference solutions" in capsys.readouterr().err


def test_worker_uids_are_unique_per_worker():
    assert sandbox.worker_uid(100) != sandbox.worker_uid(101)
    assert sandbox.worker_uid(4_194_304) < 2**32 - 2
