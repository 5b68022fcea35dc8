"""processes.read_proc: /proc files kept open are read afresh, and a gone process reads as gone."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import pytest

from robolab.grading.isolation import processes

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


def test_a_kept_file_is_read_afresh():
    before = processes.last_pid()
    subprocess.run(["true"], check=True)
    after = processes.last_pid()
    assert after > before or after < before - 1000  # a new pid (or the counter wrapped)


def test_a_process_that_was_reaped_reads_as_gone_and_its_number_is_read_anew():
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(0.2)"])
    assert processes._stat(proc.pid) is not None
    assert processes.run_delay(proc.pid) is not None
    proc.wait()
    assert processes._stat(proc.pid) is None  # the kept descriptor fails: ESRCH
    assert processes.run_delay(proc.pid) is None
    assert f"/proc/{proc.pid}/stat" not in processes._open


def test_each_thread_reads_its_own_schedstat():
    mine = processes.run_delay()
    seen = []
    thread = threading.Thread(target=lambda: seen.append(processes.run_delay()))
    thread.start()
    thread.join()
    assert mine is not None and seen[0] is not None
    keys = [k for k in processes._open if k.startswith("/proc/self/task/")]
    assert len(set(keys)) >= 2  # one file per thread, not the first thread's for both


def test_at_most_a_bounded_number_of_files_stay_open():
    for _ in range(processes._OPEN_MAX + 10):
        proc = subprocess.Popen(["sleep", "5"])
        try:
            processes._stat(proc.pid)
        finally:
            proc.kill()
            proc.wait()
    assert len(processes._open) <= processes._OPEN_MAX


def test_a_thread_is_not_a_member_of_its_process_group():
    """``/proc/<tid>/stat`` exists for a thread and reads as its whole process: a scan of
    new pids that took it for a process would charge the process's CPU time twice and
    kill the process when it swept the "member" away."""
    program = "import threading, sys; threading.Thread(target=sys.stdin.read).start(); print(1)"
    proc = subprocess.Popen(
        [sys.executable, "-c", program],
        start_new_session=True,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
    )
    try:
        proc.stdout.readline()  # its second thread is running
        tids = [int(t) for t in os.listdir(f"/proc/{proc.pid}/task")]
        assert len(tids) == 2
        scanned = processes.group_members(proc.pid, range(min(tids), max(tids) + 1))
        assert [m.pid for m in scanned] == [proc.pid]
        assert [m.pid for m in processes.group_members(proc.pid)] == [proc.pid]
    finally:
        proc.kill()
        proc.wait()
