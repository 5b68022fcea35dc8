"""Stop requests (robolab.grading.running.stopping): signals only count, runs are stopped bounded.

The whole path (robolab grade interrupted at several moments, both signals, resumed) is
tests/grading/course/test_batch.py::test_interrupt_leaves_a_valid_partial_gradebook_and_resumes.
"""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from robolab.grading.running import stopping
from tests.grading.sigint import sigint_default


@pytest.fixture
def handlers():
    """Put back SIGINT's and SIGTERM's handlers whatever the test leaves."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)


def test_signals_request_a_stop_and_raise_nothing(handlers):
    signal.signal(signal.SIGINT, signal.default_int_handler)
    with stopping.on_signals():
        assert not stopping.requested()
        signal.raise_signal(signal.SIGINT)  # its handler has run when this returns
        assert stopping.requested() and not stopping.hurried()
        signal.raise_signal(signal.SIGTERM)
        assert stopping.hurried() and stopping.signals_seen() == 2
    # a stopped command is about to exit: later signals must not kill or raise in it
    assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_IGN
    # nor does the request outlive its block: a batch run later as a library (in the
    # same process: a test suite, a notebook) is not stopped by it
    assert not stopping.requested() and not stopping.hurried()


def test_handlers_come_back_when_nothing_was_requested(handlers):
    signal.signal(signal.SIGINT, signal.default_int_handler)
    before = signal.getsignal(signal.SIGTERM)
    with stopping.on_signals():
        with stopping.on_signals():  # nested: the outer block listens
            pass
        assert signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.getsignal(signal.SIGTERM) == before
    assert not stopping.requested()


def test_an_inherited_ignored_sigint_stays_ignored(handlers):
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with stopping.on_signals():
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
        signal.raise_signal(signal.SIGINT)
        assert not stopping.requested()
        signal.raise_signal(signal.SIGTERM)  # SIGTERM still stops
        assert stopping.requested()


_SLEEP = "import time\ntime.sleep(600)"


def _child(code: str) -> subprocess.Popen:
    """A Python child that says when it is ready, in our process group (not a leader)."""
    with sigint_default():
        proc = subprocess.Popen(
            [sys.executable, "-c", f"{code}\nprint('ready', flush=True)\n{_SLEEP}"],
            stdout=subprocess.PIPE,
            text=True,
        )
    assert proc.stdout.readline().strip() == "ready"
    return proc


def test_a_run_that_leads_no_process_group_yet_is_still_stopped(handlers):
    """A run forked a moment ago may not have called setsid yet: killpg then fails."""
    proc = _child("pass")
    try:
        stopping.stop_run(proc)
        assert proc.poll() == -signal.SIGINT  # SIGINT itself, no need for the SIGKILL
    finally:
        proc.kill()
        proc.wait()


def test_a_run_ignoring_sigint_is_killed_after_the_grace(monkeypatch):
    monkeypatch.setattr(stopping, "GRACE", 0.5)
    proc = _child("import signal; signal.signal(signal.SIGINT, signal.SIG_IGN)")
    try:
        stopping.stop_run(proc)
        assert proc.poll() == -signal.SIGKILL
    finally:
        proc.kill()
        proc.wait()
