"""Stopping a batch on SIGINT or SIGTERM: one request, looked at where stopping is safe.

Python's own Ctrl-C handling raises :class:`KeyboardInterrupt` in the main thread at
whatever bytecode it happens to run: inside a ``finally``, between a lock's ``acquire``
and the ``try`` that releases it, inside a thread pool's ``shutdown``. A grader that is
then left holding a lock that a worker thread needs waits forever. So ``robolab grade``
does not let a signal raise anything: :func:`on_signals` turns SIGINT and SIGTERM into
a *stop request* (a counter, the only thing the handler touches: no lock, no
:class:`threading.Event`, since the handler runs in the middle of whatever the main
thread holds), and the batch (:func:`robolab.grading.running.runner.grade_all`) looks at
it between waits of at most a fifth of a second:

- the first signal asks for a stop: no new pytest run starts, each running one gets
  SIGINT (its fixtures close the student's worker) and SIGKILL after a grace period,
  what finished is written down, the command exits 130;
- a second signal (either one) means *stop now*: the pytest runs get SIGKILL at once.

Either way stopping is bounded. A SIGINT that the process inherited as ignored (a
background job of a script, ``cmd &``) stays ignored, as for any command: such a batch
stops on SIGTERM.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import threading
import time
from collections.abc import Iterator

__all__ = [
    "GRACE",
    "REAP",
    "TICK",
    "allow_runs",
    "forget_run",
    "hurried",
    "on_signals",
    "remember_run",
    "requested",
    "runs_stopping",
    "signals_seen",
    "stop_run",
    "stop_running",
]

#: Seconds between asking pytest to stop (SIGINT: fixtures close the worker) and killing it.
GRACE = 5.0
#: Seconds a pytest run (or the thread grading it) gets to be gone once SIGKILLed.
REAP = 5.0
#: Seconds between two looks at a stop request (by the batch and by each run's thread).
TICK = 0.2

#: Signals received since :func:`on_signals` started listening (only the handler writes it).
_seen = 0
#: How many :func:`on_signals` blocks are open (the outermost one listens).
_depth = 0


def _handler(signum: int, frame) -> None:
    global _seen
    _seen += 1  # nothing else: see the module's docstring


def signals_seen() -> int:
    """How many stop signals arrived since :func:`on_signals` started listening."""
    return _seen


def requested() -> bool:
    """Whether a stop was asked for (one signal or more) in the open :func:`on_signals` block.

    Outside every block nothing listens (a signal raises as usual), so nothing is
    requested: a block that saw a stop must not stop a later batch run as a library.
    """
    return _depth > 0 and _seen > 0


def hurried() -> bool:
    """Whether a stop *now* was asked for (a second signal): no grace for the pytest runs."""
    return _depth > 0 and _seen > 1


@contextlib.contextmanager
def on_signals() -> Iterator[None]:
    """Within this block, SIGINT and SIGTERM request a stop instead of raising.

    Only in the main thread (elsewhere signals cannot be handled; the block then changes
    nothing). A SIGINT ignored on entry stays ignored. The previous handlers come back
    on exit, unless a stop was requested: the command is then about to exit 130, and a
    signal more (while its zygotes are closed, or the interpreter, which puts back the
    default handlers, tears down) must neither kill it nor raise a KeyboardInterrupt in
    an ``atexit`` callback: both signals are then ignored.
    """
    global _seen, _depth
    if threading.current_thread() is not threading.main_thread() or _depth:
        yield  # not the main thread, or listening already (a request then is kept)
        return
    _seen = 0
    previous = {}
    _depth += 1
    try:
        for sig in (signal.SIGTERM, signal.SIGINT):
            if sig == signal.SIGINT and signal.getsignal(sig) == signal.SIG_IGN:
                continue
            previous[sig] = signal.signal(sig, _handler)
        yield
    finally:
        stopped = requested()
        _depth -= 1
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_IGN if stopped else handler)


# --- the pytest runs of this process, and stopping them ---------------------------------

#: pytest runs under way (for stop_running).
_live: set[subprocess.Popen] = set()
_live_lock = threading.Lock()
#: Set by stop_running: no new pytest run starts until allow_runs (the next batch).
_stopping = threading.Event()


def remember_run(proc: subprocess.Popen) -> None:
    """Count ``proc`` (a pytest run: a Popen or a WarmChild) among the runs under way."""
    with _live_lock:
        _live.add(proc)


def forget_run(proc: subprocess.Popen) -> None:
    with _live_lock:
        _live.discard(proc)


def runs_stopping() -> bool:
    """Whether :func:`stop_running` was called (since the last :func:`allow_runs`)."""
    return _stopping.is_set()


def allow_runs() -> None:
    """A new batch: runs may start again."""
    _stopping.clear()


def _signal_run(proc: subprocess.Popen, sig: int) -> bool:
    """Send ``sig`` to the run's process group; False when the run is gone.

    A run forked a moment ago may not lead its own group yet: then it gets ``sig`` itself
    (it has started nothing of its own).
    """
    try:
        os.killpg(proc.pid, sig)
        return True
    except ProcessLookupError:
        pass
    except PermissionError:
        return False
    if proc.poll() is not None:
        return False
    try:
        os.kill(proc.pid, sig)
        return True
    except (ProcessLookupError, PermissionError):
        return False


def stop_run(proc: subprocess.Popen) -> None:
    """SIGINT the run's process group (fixtures close the worker), then SIGKILL it.

    The SIGKILL comes after :data:`GRACE` seconds, or at once when a stop *now* is asked
    for (:func:`hurried`); bounded either way.
    """
    deadline = time.monotonic() + GRACE
    if not hurried() and _signal_run(proc, signal.SIGINT):
        while time.monotonic() < deadline and not hurried():
            try:
                proc.wait(timeout=TICK)
                return
            except subprocess.TimeoutExpired:
                continue
    if proc.poll() is None and _signal_run(proc, signal.SIGKILL):
        try:
            proc.wait(timeout=REAP)
        except subprocess.TimeoutExpired:
            pass


def stop_running() -> int:
    """Stop every pytest run this process started that is still running; return how many.

    No new run starts until :func:`allow_runs`. Each run's own thread sees the request
    within :data:`TICK` and stops its run (:func:`stop_run`); this waits for that,
    bounded: a run still there after the grace is SIGKILLed here.
    """
    _stopping.set()
    with _live_lock:
        running = list(_live)
    deadline = time.monotonic() + GRACE + REAP
    for proc in running:
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            _signal_run(proc, signal.SIGKILL)
            try:
                proc.wait(timeout=REAP)
            except subprocess.TimeoutExpired:
                pass
        except Exception:  # noqa: BLE001 - gone already
            pass
    return len(running)
