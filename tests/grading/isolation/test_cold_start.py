"""What makes a cold ``robolab grade one.ipynb`` fast, pinned as behaviour (never as time).

- both zygotes are started at once, before anything waits for either;
- the protection probe is forked from the grader zygote (the grader process imports
  neither numpy nor the proxy for it) and does not count as a submission for the
  worker zygote's idle imports;
- a zygote still importing is killed, not waited for, when its grader closes it;
- the codec imports robolab.maps (scipy) only for a result that names it.

``benchmarks/grading.py`` measures the seconds.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from robolab.grading.isolation import protection, warm, zygote
from robolab.grading.running.proxy import open_submission
from robolab.grading.running.runner import start_zygotes
from tests.grading import TEST_LIMITS, wait_for_idle_import, write_notebook

REPO = Path(__file__).resolve().parents[3]
warm_only = pytest.mark.skipif(
    sys.platform != "linux" or os.environ.get(warm.SWITCH_VARIABLE) == "0",
    reason="warm workers need Linux (fork, descriptor passing) and are switched off",
)

LOADED = """
import sys

def loaded(name):
    return name in sys.modules
"""


def _python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=REPO,
    )


@pytest.fixture
def fresh():
    """No zygote of this process before the test, none after it."""
    warm.reset_shared(None)
    protection.describe_protection.cache_clear()
    protection.batch_protection.cache_clear()
    yield
    warm.reset_shared(None)
    protection.describe_protection.cache_clear()
    protection.batch_protection.cache_clear()


@warm_only
def test_both_zygotes_start_at_once_and_nothing_waits_for_them(fresh):
    start_zygotes(REPO)
    workers = warm.shared()
    running = warm.running_graders()
    assert workers is not None and len(running) == 1
    root, grader = running[0]
    assert root == str(REPO.resolve())
    # Both processes exist, and neither has finished importing: start_zygotes returned
    # without waiting for the first (the ready byte is not there yet for either).
    for z in (workers, grader):
        assert z.process.poll() is None
        assert z._ready is not None
    assert workers.process.args[-2:-1] == ["robolab.grading.isolation.zygote"]
    assert "-I" in workers.process.args  # the worker zygote: isolated, like a cold worker
    assert "-I" not in grader.process.args  # the grader zygote: the grader's environment
    start_zygotes(REPO)  # a second call starts nothing new
    assert warm.shared() is workers and warm.running_graders() == [(root, grader)]


def test_start_zygotes_starts_nothing_when_warm_grading_is_off(fresh, monkeypatch):
    monkeypatch.setenv(warm.SWITCH_VARIABLE, "0")
    start_zygotes(REPO)
    assert warm.shared() is None and warm.running_graders() == []


@warm_only
def test_a_zygote_still_importing_is_killed_not_waited_for(fresh):
    z = warm.Zygote()
    z.close()  # at once: it is still importing numpy and matplotlib
    assert z.process.returncode == -9
    ready = warm.Zygote()
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # wait for its ready byte (it forks from then on)
        try:
            if os.read(ready._ready, 1):
                os.close(ready._ready)
                ready._ready = None
                break
        except BlockingIOError:
            time.sleep(0.05)
    ready.close()
    assert ready.process.returncode == 0  # ready: it exits by itself when closed


@warm_only
def test_the_probe_is_forked_from_the_grader_zygote(fresh):
    start_zygotes(REPO)
    forked = protection._probe_forked()
    assert forked is not None  # not a fallback to probing in this process
    in_process = protection.probe_protection()
    assert forked.report is not None and in_process.report is not None
    assert forked.line() == in_process.line()
    assert forked.answers_protected == in_process.answers_protected
    assert forked.readable == in_process.readable and forked.reached == in_process.reached
    assert protection.Protection.from_dict(json.loads(json.dumps(forked.to_dict()))) == forked


@warm_only
def test_a_grader_zygote_of_another_robolab_does_not_probe(fresh, tmp_path):
    other = tmp_path / "course"
    (other / "robolab").mkdir(parents=True)  # a root with a robolab copy of its own
    start_zygotes(other)
    assert [root for root, _ in warm.running_graders()] == [str(other.resolve())]
    assert protection._probe_forked() is None  # probed by this process's robolab instead


def test_without_a_grader_zygote_the_probe_runs_here(fresh, monkeypatch):
    monkeypatch.setenv(warm.SWITCH_VARIABLE, "0")
    assert protection._probe_forked() is None
    found = protection.batch_protection()
    assert found.report is not None and found is protection.describe_protection()


@warm_only
def test_a_batch_does_not_import_numpy_in_the_grader_process_to_probe():
    done = _python(
        f"""
        import sys
        from pathlib import Path
        from robolab.grading.running.runner import grade_all
        [result] = grade_all([Path({str(REPO / "examples/submissions/demo/correct.ipynb")!r})],
                             lab="demo", progress=False)
        assert result.total == result.max_points, result.errors
        print(sorted(m for m in ("numpy", "robolab.grading.running.proxy",
                                 "robolab.grading.wire.codec")
                     if m in sys.modules))
        """
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
    assert done.stderr.count("isolation: ") == 1  # the probe's line, once


@warm_only
def test_the_probe_does_not_count_towards_the_idle_imports(fresh, tmp_path):
    first_idle = zygote.PRELOAD_IDLE[0]
    notebook = write_notebook(tmp_path / "loaded.ipynb", LOADED)
    with warm.probing(), open_submission(notebook, limits=TEST_LIMITS) as probe:
        assert not probe.loaded(first_idle)
    with open_submission(notebook, limits=TEST_LIMITS) as first:
        assert not first.loaded(first_idle)  # not preloaded: only an idle import
    time.sleep(1.0)  # idle; had the probe counted, two requests would have started them
    with open_submission(notebook, limits=TEST_LIMITS) as second:
        assert not second.loaded(first_idle)
    wait_for_idle_import(notebook, first_idle)  # ... and after a second submission they do start


def test_a_plain_result_does_not_import_robolab_maps():
    done = _python(
        """
        import sys
        import numpy as np
        from robolab.grading.wire import codec
        value = codec.loads(codec.dumps({"x": np.arange(3), "s": "robolab", "f": 1.5}))
        assert value["s"] == "robolab"
        print("robolab.maps" in sys.modules, "scipy.special" in sys.modules)
        from robolab.maps import OccupancyGrid
        grid = OccupancyGrid(np.zeros((2, 3)), 0.5, (0.0, 0.0, 0.0))
        data = codec.dumps(grid)
        # registered on demand, from the bytes that name the module
        assert type(codec.loads(data)).__name__ == "OccupancyGrid"
        print("ok")
        """
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "False", "ok"]
