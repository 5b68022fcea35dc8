"""Limits that do not depend on the machine (docs/grading.md, section 3).

"Too slow" is decided by CPU time, against a budget scaled to the reference solution's
CPU time; wall-clock limits are a backstop counted on a clock that leaves out the time a
process waited for a CPU; loading the notebook (again, after a crash) is charged like a
call; and whatever a limit cut short is flagged to the instructor. No test here measures
how long something took on the wall clock.
"""

from __future__ import annotations

import importlib
import json
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from robolab.grading.isolation import processes
from robolab.grading.labs import discover_labs
from robolab.grading.running.limits import BUDGET_FACTOR
from robolab.grading.running.proxy import (
    Limits,
    WorkerCrashed,
    WorkerTimeout,
    open_submission,
    reference_limits,
)
from tests.grading import TEST_LIMITS, write_notebook

REPO = Path(__file__).resolve().parents[3]
#: A correct solution this many times slower than the reference, in CPU, keeps full marks.
SLOWER = 5.0


def test_reference_limits_scale_with_the_reference_cpu_time():
    """8x the reference's CPU (at least 20 s), a wall backstop twice that (at least 60 s)."""
    got = reference_limits(Limits(), 15.0)
    assert (got.total_cpu_seconds, got.total_wall_seconds) == (120.0, 240.0)
    assert got.cpu_budget_seconds == 120.0 and got.budget_seconds == 240.0
    floor = reference_limits(Limits(), 1.0)
    assert (floor.total_cpu_seconds, floor.total_wall_seconds) == (20.0, 60.0)
    # never above the defaults: five per-call limits
    capped = reference_limits(Limits(cpu_seconds=2.0, wall_seconds=5.0), 15.0)
    assert (capped.total_cpu_seconds, capped.total_wall_seconds) == (10.0, 25.0)
    # totals given explicitly are kept
    mine = reference_limits(Limits(total_cpu_seconds=7.0, total_wall_seconds=9.0), 15.0)
    assert (mine.total_cpu_seconds, mine.total_wall_seconds) == (7.0, 9.0)
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ValueError, match="reference_cpu_seconds"):
            reference_limits(Limits(), bad)


@pytest.mark.parametrize("lab", [lab.name for lab in discover_labs()])
def test_every_lab_gives_a_5x_slower_solution_room(lab):
    """Each lab's hidden tests state the reference's CPU time; 5x that fits with room."""
    module = importlib.import_module(f"tests.labs.test_{lab}")
    reference = getattr(module, "REFERENCE_CPU_SECONDS", 0)
    assert reference > 0, f"tests/labs/test_{lab}.py has no REFERENCE_CPU_SECONDS"
    limits = reference_limits(Limits(**getattr(module, "GRADING_LIMITS", {})), reference)
    # CPU time grows a little on a busy machine (shared caches): keep a margin of 1.5
    assert limits.cpu_budget_seconds >= 1.5 * SLOWER * reference
    assert limits.budget_seconds >= 2 * limits.cpu_budget_seconds or limits.budget_seconds >= 60
    assert BUDGET_FACTOR >= 1.5 * SLOWER


def _spinner(cpu: int) -> subprocess.Popen:
    """A busy loop pinned to ``cpu``, in a session of its own (as an independent program)."""
    proc = subprocess.Popen(
        [sys.executable, "-c", "while True: pass"],
        start_new_session=True,
        stdin=subprocess.DEVNULL,
    )
    os.sched_setaffinity(proc.pid, {cpu})
    return proc


def _on_cpu(task: int | str) -> float:
    """Seconds a process's main thread (a pid) or a task (its schedstat path) has run."""
    with open(task if isinstance(task, str) else f"/proc/{task}/schedstat", "rb") as f:
        return int(f.read().split()[0]) / 1e9


@pytest.mark.skipif(processes.run_delay(os.getpid()) is None, reason="no /proc/<pid>/schedstat")
def test_the_awake_clock_leaves_out_waiting_for_a_cpu():
    """A busy loop sharing its core with another runs about half the time; what the wall
    limits count is the half it ran (it never sleeps), however loaded the machine is."""
    cpu = min(os.sched_getaffinity(0))
    watched, rival = _spinner(cpu), _spinner(cpu)
    try:
        clock = processes.AwakeClock(watched.pid)
        start = _on_cpu(watched.pid)
        while _on_cpu(watched.pid) - start < 0.5:  # until it has run half a second
            os.sched_yield()
        awake, ran = clock.elapsed(), _on_cpu(watched.pid) - start
        waited = processes.run_delay(watched.pid)
    finally:
        for proc in (watched, rival):
            proc.kill()
            proc.wait()
    assert ran >= 0.5 and waited is not None and waited > 0
    assert abs(awake - ran) <= 0.05 + 0.1 * ran, (awake, ran)


#: A program whose main thread waits for a thread (or a forked child, argv[1]) that
#: computes for ever, started once the program is told to.
_DELEGATE = """
import os, sys, threading
def spin():
    while True:
        pass
sys.stdin.readline()
if sys.argv[1] == "thread":
    worker = threading.Thread(target=spin)
    worker.start()
    worker.join()
elif os.fork() == 0:
    spin()
else:
    os.wait()
"""


def _helper_task(pid: int, clock: processes.AwakeClock) -> str:
    """The schedstat path of ``pid``'s other thread or its child, once there is one
    (reading ``clock`` meanwhile, as the grader does every 0.05 s)."""
    while True:
        clock.elapsed()
        tasks = [t for t in os.listdir(f"/proc/{pid}/task") if t != str(pid)]
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            children = f.read().split()
        if tasks or children:
            return f"/proc/{(tasks or children)[0]}/schedstat"
        time.sleep(0.001)


@pytest.mark.skipif(processes.run_delay(os.getpid()) is None, reason="no /proc/<pid>/schedstat")
@pytest.mark.parametrize("where", ["thread", "child"])
def test_a_thread_or_child_waiting_for_a_cpu_is_waiting_too(where):
    """A process whose main thread waits for a thread (or a child) that computes beside a
    busy loop on its core: the wall limits count the half the computation ran, as when
    the main thread computes itself, not the half it waited for the core."""
    cpu = min(os.sched_getaffinity(0))
    delegating = subprocess.Popen(
        [sys.executable, "-c", _DELEGATE, where], start_new_session=True, stdin=subprocess.PIPE
    )
    rival = _spinner(cpu)
    try:
        os.sched_setaffinity(delegating.pid, {cpu})  # the thread or child inherits it
        clock = processes.AwakeClock(delegating.pid)
        delegating.stdin.write(b"go\n")
        delegating.stdin.flush()
        task = _helper_task(delegating.pid, clock)
        start = _on_cpu(task)
        while _on_cpu(task) - start < 0.5:
            clock.elapsed()
            time.sleep(0.005)
        awake, ran = clock.elapsed(), _on_cpu(task) - start
        waited = processes.run_delay(task.split("/")[2])
    finally:
        for proc in (delegating, rival):
            os.killpg(proc.pid, signal.SIGKILL)  # the forked child too (its own session)
            proc.wait()
    assert waited is not None and waited > 0.2  # it did wait for the core
    assert abs(awake - ran) <= 0.05 + 0.1 * ran, (awake, ran, waited)


def test_a_sleeping_process_is_awake_all_along():
    proc = subprocess.Popen(["sleep", "30"], start_new_session=True)
    try:
        clock = processes.AwakeClock(proc.pid)
        before = processes.run_delay(proc.pid)
        while clock.elapsed() < 0.3:
            os.sched_yield()
        # sleeping is never waiting for a CPU: its run delay did not move
        assert processes.run_delay(proc.pid) == pytest.approx(before, abs=0.01)
    finally:
        proc.kill()
        proc.wait()


BURN = """
import os
import time

def burn(seconds):
    start = time.process_time()
    while time.process_time() - start < seconds:
        pass

burn(LOAD_CPU)  # a needed cell: `work` reads LOAD_CPU

def work():
    return LOAD_CPU

def crash():
    os._exit(1)
"""


def test_loading_is_charged_to_the_cpu_budget_and_reloads_too(tmp_path):
    path = write_notebook(tmp_path / "burn.ipynb", "LOAD_CPU = 0.6", BURN, lab=None)
    limits = replace(TEST_LIMITS, cpu_seconds=2, total_cpu_seconds=2.0, total_wall_seconds=60)
    with open_submission(path, limits=limits) as sub:
        assert sub.problems == []
        # The kernel reports a process's user and system time each in whole clock ticks,
        # so the charge can read up to two ticks under the 0.6 s the cell burned.
        tick = 1 / os.sysconf("SC_CLK_TCK")
        assert 0.6 - 2 * tick <= sub.spent_cpu_seconds < 1.0  # the first load
        assert sub.work() == 0.6
        outcomes = []
        for _ in range(6):  # every crash makes the next call load the notebook again
            try:
                sub.crash()
            except (WorkerCrashed, WorkerTimeout) as exc:
                outcomes.append(exc)
        # 2 s of CPU: the first load and two reloads (1.8 s), then a reload is cut short
        # and every later call is not run: reloads are not free.
        crashes = [o for o in outcomes if isinstance(o, WorkerCrashed)]
        assert len(crashes) in (2, 3) and outcomes[: len(crashes)] == crashes, outcomes
        assert "total CPU time budget of 2 s" in str(outcomes[-1])
        assert "not run" in str(outcomes[-1])
        assert sub.spent_cpu_seconds >= 1.8
        assert any("not run" in line for line in sub.limits_hit())


def test_a_limit_that_cut_a_submission_short_is_flagged_in_the_gradebook(tmp_path, capsys):
    """The instructor sees it: in the row's flags and in the summary."""
    from robolab.cli import main

    correct = json.loads((REPO / "examples/submissions/demo/correct.ipynb").read_text())
    for cell in correct["cells"]:
        text = "".join(cell["source"])
        if cell["cell_type"] == "code" and text.lstrip().startswith("def wrap"):
            cell["source"] = ["def wrap(angle):\n", "    while True:\n", "        pass\n"]
    hanging = tmp_path / "hangs.ipynb"
    hanging.write_text(json.dumps(correct))
    out = tmp_path / "grades"
    assert main(["grade", str(hanging), "--out", str(out), "--lab", "demo"]) == 0
    printed = capsys.readouterr().out
    [row] = json.loads((out / "gradebook.json").read_text())
    assert row["total"] < 100 and row["cpu_seconds"] > 0
    limits = [f for f in row["flags"] if f.startswith("limit: ")]
    assert any(f.startswith("limit: wrap(): timed out") for f in limits), row["flags"]
    assert "FLAG: limit: wrap()" in printed and "FLAGGED: 1 submission(s)" in printed
