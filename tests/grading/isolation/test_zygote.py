"""Warm workers (grading/isolation/zygote.py): forked from a clean zygote, isolated like cold ones.

The sandbox and hostile tests already run through the warm path (it is the
default); these tests pin what the fork server adds: the worker really is a
fork of a clean zygote, nothing crosses from one submission to the next, the
answers are never in the zygote's memory, a dead grader or a dead zygote
leaves no worker running, and grading warm gives the same scores as cold.
"""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from robolab.grading.isolation import sandbox, warm, zygote
from robolab.grading.running.proxy import WorkerCrashed, open_submission
from robolab.grading.running.runner import grade_submission
from tests.grading import TEST_LIMITS, wait_for_idle_import, write_notebook

REPO = Path(__file__).resolve().parents[3]
pytestmark = pytest.mark.skipif(
    sys.platform != "linux" or os.environ.get(warm.SWITCH_VARIABLE) == "0",
    reason="warm workers need Linux (fork, descriptor passing) and are switched off",
)

STATE = """
import os
import sys
import numpy as np

def tamper():
    np.allclose = lambda *a, **k: True
    sys.modules["numpy"].TAMPERED = True
    os.environ["TAMPERED"] = "1"
    return True

def looks_clean():
    return (not hasattr(np, "TAMPERED"), np.allclose([0.0], [1.0]) is False,
            "TAMPERED" not in os.environ)

def draw():
    return float(np.random.random())

def answers_in_memory():
    return sorted(m for m in sys.modules if m.partition(".")[0] in ("solutions", "tests"))

def parent():
    return os.getppid()

def loaded(name):
    return name in sys.modules

def hang():
    while True:
        pass
"""


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie does not)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False
    return "\nState:\tZ" not in status


def _wait_dead(pid: int, seconds: float = 120.0) -> bool:
    deadline = time.monotonic() + seconds
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not _alive(pid)


def _cmdline(pid: int) -> list[str]:
    with open(f"/proc/{pid}/cmdline", "rb") as f:
        return [part.decode() for part in f.read().split(b"\0") if part]


@pytest.fixture
def running():
    """This process's zygote (started by the first test that needs it), left running."""
    shared = warm.shared()
    if shared.process is None or shared.process.poll() is not None:
        warm.reset_shared(None)  # inherited or dead: a zygote of this process's own
        shared = warm.shared()
    return shared


@pytest.fixture
def fresh_zygote():
    """A zygote of this test's own, for the tests that kill or close it."""
    warm.reset_shared(None)
    yield warm.shared()
    warm.reset_shared(None)


@pytest.fixture
def notebook(tmp_path):
    return write_notebook(tmp_path / "state.ipynb", STATE)


def test_the_worker_is_a_fork_of_a_clean_zygote(running, notebook):
    with open_submission(notebook, limits=TEST_LIMITS) as sub:
        parent = sub.parent()
        assert parent == running.process.pid != os.getpid()
        # The zygote is started like a cold worker: isolated mode, no bytecode, its own module.
        assert _cmdline(parent)[1:4] == ["-I", "-B", "-m"]
        assert _cmdline(parent)[4] == "robolab.grading.isolation.zygote"
        assert sub.answers_in_memory() == []
        assert sub.sandbox.uid == sandbox.worker_uid(sub._worker.process.pid) or os.geteuid() != 0


def test_isolation_is_the_same_as_a_cold_worker(running, notebook, monkeypatch):
    with open_submission(notebook, limits=TEST_LIMITS) as forked:
        warm_report = forked.sandbox
        warm_pid = forked._worker.process.pid
    monkeypatch.setenv(warm.SWITCH_VARIABLE, "0")
    with open_submission(notebook, limits=TEST_LIMITS) as cold:
        assert isinstance(cold._worker.process, subprocess.Popen)  # started the old way
        assert cold.parent() == os.getpid()
        cold_report = cold.sandbox
    fields = dataclasses.asdict(warm_report)
    assert fields.pop("uid") != dataclasses.asdict(cold_report).pop("uid") or os.geteuid() != 0
    cold_fields = dataclasses.asdict(cold_report)
    cold_fields.pop("uid")
    assert fields == cold_fields
    assert warm_report.protects_answers
    assert not _alive(warm_pid)


def test_nothing_crosses_from_one_submission_to_the_next(running, notebook):
    with open_submission(notebook, limits=TEST_LIMITS) as first:
        assert first.tamper() is True
        assert first.looks_clean() == (False, False, False)
        first_draw = first.draw()
    with open_submission(notebook, limits=TEST_LIMITS) as second:
        assert second.looks_clean() == (True, True, True)
        # numpy's global random state is reseeded in each child, not copied from the zygote.
        assert second.draw() != first_draw


def test_a_batch_gets_the_idle_imports_and_one_submission_does_not_pay_for_them(
    fresh_zygote, notebook
):
    last = zygote.PRELOAD_IDLE[-1]
    with open_submission(notebook, limits=TEST_LIMITS) as first:
        assert first.loaded("matplotlib.pyplot") and first.loaded("robolab.plotting")
    time.sleep(0.5)  # idle, but it has served one submission only
    with open_submission(notebook, limits=TEST_LIMITS) as second:
        assert not second.loaded(last)
    wait_for_idle_import(notebook, last)


def test_a_crash_restarts_a_warm_worker(running, tmp_path):
    path = write_notebook(
        tmp_path / "crash.ipynb", "import os\ndef die():\n    os._exit(3)\ndef one():\n    return 1"
    )
    with open_submission(path, limits=TEST_LIMITS) as sub:
        first = sub._worker.process.pid
        with pytest.raises(WorkerCrashed, match="status 3"):
            sub.die()
        assert sub.one() == 1
        assert sub._worker.process.pid != first and _wait_dead(first)


def test_a_killed_worker_reports_its_signal(running, notebook):
    with open_submission(notebook, limits=TEST_LIMITS) as sub:
        pid = sub._worker.process.pid
        os.kill(pid, signal.SIGSEGV)
        assert sub._worker.process.wait(timeout=120) == -signal.SIGSEGV


GRADER = """
import sys
from robolab.grading.running.proxy import Limits, open_submission
sub = open_submission(sys.argv[1], limits=Limits(cpu_seconds=600, wall_seconds=600))
print(sub._worker.process.pid, flush=True)
sub.hang()
"""


def test_a_dead_grader_leaves_no_worker_running(running, notebook):
    """SIGKILL the grader while its student code loops: the zygote kills the worker."""
    env = dict(os.environ, **{warm.FD_VARIABLE: str(running.fileno())})
    grader = subprocess.Popen(
        [sys.executable, "-c", GRADER, str(notebook)],
        stdout=subprocess.PIPE,
        env=env,
        pass_fds=(running.fileno(),),
        cwd=REPO,
    )
    worker = int(grader.stdout.readline())
    assert _alive(worker)
    time.sleep(0.3)  # it is in the loop now
    grader.kill()
    grader.wait()
    assert _wait_dead(worker), "the worker outlived its grader"


def test_a_dead_zygote_takes_its_workers_and_the_next_worker_starts_anyway(fresh_zygote, notebook):
    with open_submission(notebook, limits=TEST_LIMITS) as sub:
        worker = sub._worker.process.pid
        fresh_zygote.process.kill()
        assert _wait_dead(worker), "a worker outlived its zygote"
        # The proxy sees a crash and the next call gets a fresh worker from a fresh zygote.
        with pytest.raises(WorkerCrashed):
            sub.hang()
        assert sub.looks_clean() == (True, True, True)
        assert warm.shared() is not fresh_zygote
        assert sub.parent() == warm.shared().process.pid


def test_the_zygote_exits_when_every_grader_has_gone(fresh_zygote, notebook):
    sub = open_submission(notebook, limits=TEST_LIMITS)
    worker = sub._worker.process.pid
    process = fresh_zygote.process
    fresh_zygote.control.close()  # the grader's last handle on it
    process.wait(timeout=120)
    assert _wait_dead(worker)
    sub.close()


def test_a_stale_descriptor_variable_is_not_trusted(monkeypatch, tmp_path):
    warm.reset_shared(None)
    with open(tmp_path / "file", "w") as f:
        monkeypatch.setenv(warm.FD_VARIABLE, str(f.fileno()))  # a file, not a control socket
        try:
            started = warm.shared()
            assert started is not None and started.process is not None  # started its own
            assert not f.closed and os.fstat(f.fileno())
        finally:
            warm.reset_shared(None)


def test_warm_and_cold_grading_give_the_same_scores(monkeypatch):
    """The whole path: runner -> grader zygote -> pytest -> worker zygote, against cold."""
    partial = REPO / "examples" / "submissions" / "bayes" / "partial.ipynb"
    outcomes = {}
    for mode in ("warm", "cold"):
        warm.reset_shared(None)
        if mode == "cold":
            monkeypatch.setenv(warm.SWITCH_VARIABLE, "0")
        result = grade_submission(partial)
        assert not result.errors, result.errors
        outcomes[mode] = [(t.nodeid, t.outcome, t.message) for t in result.tests]
        if mode == "warm":
            assert str(REPO) in warm._graders  # it did go through the grader zygote
    warm.reset_shared(None)
    assert outcomes["warm"] == outcomes["cold"]
    assert {o for _, o, _ in outcomes["warm"]} == {"passed", "failed"}


def test_a_warm_pytest_run_that_times_out_is_stopped(tmp_path):
    path = write_notebook(
        tmp_path / "loop.ipynb",
        textwrap.dedent(
            """
            def bayes_posterior(*args, **kwargs):
                while True:
                    pass
            """
        ),
        lab="bayes",
    )
    warm.reset_shared(None)
    result = grade_submission(path, timeout=3)
    assert any("timed out" in e for e in result.errors), result.errors
    assert result.limits == ["grading stopped at the batch's timeout of 3 s"]
    warm.reset_shared(None)


def test_a_dead_grader_zygote_is_replaced():
    partial = REPO / "examples" / "submissions" / "bayes" / "partial.ipynb"
    warm.reset_shared(None)
    first = grade_submission(partial)
    dead = warm._graders[str(REPO)]
    dead.process.kill()
    dead.process.wait()
    second = grade_submission(partial)
    assert not second.errors and second.total == first.total > 0
    assert warm._graders[str(REPO)] is not dead
    warm.reset_shared(None)
