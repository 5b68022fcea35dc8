"""Hostile submissions (examples/submissions/hostile/) earn nothing and harm nothing.

Each notebook attacks `normalize` of the demo lab while its `wrap` and
`mean_pose` are correct. For each: calling `normalize` with valid input fails
(StudentCodeError, or a value no hidden test can accept) in bounded time, the
grader process is unharmed, and the correct functions still work afterwards.
"""

from __future__ import annotations

import dataclasses
import os
import resource
import socket
import time
from pathlib import Path

import numpy as np
import pytest

import robolab
from robolab.grading.isolation import processes
from robolab.grading.loading.notebook import NotebookError
from robolab.grading.running.proxy import (
    StudentCodeError,
    WorkerCrashed,
    WorkerTimeout,
    open_submission,
)
from tests.grading import TEST_LIMITS

HOSTILE = Path(robolab.__file__).resolve().parent.parent / "examples" / "submissions" / "hostile"
PICKLE_MARKER = Path("/tmp/robolab-hostile-pickle-payload-ran")
NETWORK_PORT = 47813
WEIGHTS = np.array([1.0, 3.0])
#: Seconds (on the clock the wall limits count, which leaves out waiting for a CPU) any
#: attack may take to be stopped with the small test limits: a limit and a reload.
BOUND = 2 * TEST_LIMITS.wall_seconds + 1

# notebook -> the error class its attack must end in (None: a returned value that is wrong).
ATTACKS = {
    "infinite_loop": WorkerTimeout,
    "huge_allocation": MemoryError,
    "fork_loop": BlockingIOError,
    "os_exit": WorkerCrashed,
    "sys_exit": WorkerCrashed,
    "import_solutions": ImportError,
    "read_tests": OSError,
    "exec_solution": OSError,
    "network": OSError,
    "monkeypatch_numpy": None,
    "always_equal": StudentCodeError,
    "pickle_payload": StudentCodeError,
    "print_flood": None,
    "structured_dtype": StudentCodeError,
    "nested_amplification": StudentCodeError,
    "huge_range": StudentCodeError,
    "huge_fraction": StudentCodeError,
    "huge_result": StudentCodeError,
    "touch_grader": None,
    "daemon": None,
    "child_cpu": WorkerTimeout,
    "slow_calls": WorkerTimeout,
    "fraction_bomb": StudentCodeError,
    "delegation_alias": NotImplementedError,
    "@formula_injection": None,
    "deep_metadata": None,
    "sleepy_reload": WorkerCrashed,
}
#: The function a notebook attacks, and its arguments, when it is not ``normalize``.
ATTACKED = {"delegation_alias": ("wrap", (np.pi,))}
#: Notebooks no step before grading can read: refused whole, with this reason.
UNREADABLE = {"deep_metadata": "nested too deeply"}
#: Attacks on the result codec: refused as a result, with a one-line reason.
RESULT_ATTACKS = {
    "structured_dtype": "dtype",
    "nested_amplification": "repeated references",
    "huge_range": "range",
    "huge_fraction": "bits",
    "huge_result": "too large",
    "pickle_payload": "not plain data",
    "always_equal": "not plain data",
    "fraction_bomb": "cost more work",
}

REAL_NUMPY = (np.allclose, np.isclose, np.testing.assert_allclose, np.testing.assert_array_equal)


def test_every_hostile_notebook_is_tested():
    assert sorted(p.stem for p in HOSTILE.glob("*.ipynb")) == sorted(ATTACKS)


@pytest.fixture
def listener():
    """Something listening where the network attack connects, to prove no connection arrives."""
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        server.bind(("127.0.0.1", NETWORK_PORT))
    except OSError:
        pytest.skip(f"port {NETWORK_PORT} is busy")
    server.listen()
    server.setblocking(False)
    yield server
    server.close()


@pytest.mark.parametrize("name", sorted(ATTACKS))
def test_hostile_submission(name, request):
    expected = ATTACKS[name]
    server = request.getfixturevalue("listener") if name == "network" else None
    PICKLE_MARKER.unlink(missing_ok=True)
    if name in ("read_tests", "exec_solution"):
        # The attack must aim at files that exist, or its failure would prove nothing.
        assert (HOSTILE.parent.parent.parent / "tests" / "labs" / "test_demo.py").exists()
        assert (HOSTILE.parent.parent.parent / "solutions" / "demo.py").exists()
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    grader_before = _grader_state()

    if name in UNREADABLE:
        with pytest.raises(NotebookError, match=UNREADABLE[name]):
            open_submission(HOSTILE / f"{name}.ipynb", lab="demo", limits=TEST_LIMITS)
        return
    attacked, args = ATTACKED.get(name, ("normalize", (WEIGHTS,)))
    with open_submission(HOSTILE / f"{name}.ipynb", lab="demo", limits=TEST_LIMITS) as sub:
        assert sub.problems == []
        spent = sub.spent_seconds, sub.spent_cpu_seconds
        if expected is None:
            got = sub.normalize(WEIGHTS)
            # What a hidden test does: compare floats with the grader's own numpy.
            assert (
                got is None
                or isinstance(got, str)
                or not np.allclose(np.asarray(got, dtype=float), [0.25, 0.75])
            )
        else:
            with pytest.raises(expected) as info:
                getattr(sub, attacked)(*args)
            assert isinstance(info.value, StudentCodeError)
            if name in RESULT_ATTACKS:
                # refused by the codec; on a busy machine the grader's decoding CPU, charged
                # to the call, may reach the call's CPU limit first: refused all the same
                assert info.value.kind in ("result", "timeout"), info.value
                reason = RESULT_ATTACKS[name] if info.value.kind == "result" else "CPU time"
                assert reason in str(info.value) and "\n" not in str(info.value)
        # Stopped by a limit, whatever the machine's load: its time is charged, and bounded.
        assert sub.spent_seconds - spent[0] < BOUND
        assert sub.spent_cpu_seconds - spent[1] < TEST_LIMITS.cpu_seconds + 2

        # ... nothing the call started is still running ...
        if sub._worker is not None:
            leader = sub._worker.process.pid
            assert [m.pid for m in processes.group_members(leader) if m.state != "Z"] == [leader], (
                "a process the call started outlived it"
            )

        # The grader is unharmed ...
        assert (
            np.allclose,
            np.isclose,
            np.testing.assert_allclose,
            np.testing.assert_array_equal,
        ) == REAL_NUMPY
        assert not PICKLE_MARKER.exists()
        if server is not None:
            with pytest.raises(BlockingIOError):
                server.accept()
        assert _grader_state() == grader_before
        if name == "print_flood":
            assert len(sub.output()) < TEST_LIMITS.max_output_bytes + 200
            assert "more bytes of output were dropped" in sub.output()
            # 100 MB went through the pipe; the grader kept 64 KiB of it.
            assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss_before < 50_000  # KiB
        if name in RESULT_ATTACKS:
            # Refused before it was read or built: the grader's peak memory barely moved.
            assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss_before < 50_000  # KiB

        # ... and the submission's correct functions still work (after a restart if needed).
        if attacked == "wrap":
            np.testing.assert_allclose(sub.normalize(WEIGHTS), [0.25, 0.75])
        else:
            assert sub.wrap(np.pi) == pytest.approx(-np.pi)
        np.testing.assert_allclose(
            sub.mean_pose([[0.0, 0.0, 3.0], [2.0, 2.0, -3.0]]), [1.0, 1.0, -np.pi], atol=1e-9
        )
        uid = sub._worker.uid if sub._worker is not None else None
    if name == "fork_loop" and uid is not None:
        _assert_no_process_of(uid)


def _grader_state() -> tuple:
    """What touch_grader tries to change in the grader."""
    return (
        resource.getrlimit(resource.RLIMIT_FSIZE),
        os.getpriority(os.PRIO_PROCESS, 0),
        sorted(os.sched_getaffinity(0)),
    )


@pytest.mark.parametrize("name", ["slow_calls", "sleepy_reload"])
def test_the_total_time_budget_stops_a_slow_submission(name):
    # Every call of slow_calls sleeps past the wall limit, every call of sleepy_reload reloads
    # a notebook that sleeps 2.5 s: without a budget that counts both, each costs a limit.
    limits = dataclasses.replace(TEST_LIMITS, wall_seconds=1, total_wall_seconds=2.5)
    if name == "sleepy_reload":
        limits = dataclasses.replace(limits, wall_seconds=4, total_wall_seconds=6)
    with open_submission(HOSTILE / f"{name}.ipynb", lab="demo", limits=limits) as sub:
        messages = []
        for _ in range(6):
            with pytest.raises((WorkerTimeout, WorkerCrashed)) as info:
                sub.normalize(WEIGHTS)
            messages.append(str(info.value))
        # The budget, then every call fails at once, even of a correct function
        # (and no worker is started for it).
        assert "total time budget" in messages[-1] and "not run" in messages[-1]
        assert messages.index(messages[-1]) <= 3  # two loads of 2.5 s, or 2.5 calls of 1 s
        with pytest.raises(WorkerTimeout, match="total time budget"):
            sub.wrap(np.pi)
        assert sub._worker is None
        assert limits.total_wall_seconds <= sub.spent_seconds <= limits.total_wall_seconds + 1
        assert any("not run" in line for line in sub.limits_hit())


def _assert_no_process_of(uid: int) -> None:
    deadline = time.monotonic() + 60  # only catches processes that never die
    while time.monotonic() < deadline:
        left = [pid for pid in os.listdir("/proc") if pid.isdigit() and _uid_of(pid) == uid]
        if not left:
            return
        time.sleep(0.05)
    raise AssertionError(f"processes of the worker's uid {uid} outlived it: {left}")


def _uid_of(pid: str) -> int | None:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("Uid:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None
