"""The limits a submission runs under: per call, per load and in total, and how they scale.

"Too slow" is decided by CPU time against the reference's (docs/grading.md section 3);
wall-clock limits, counted net of waiting for a CPU, only stop a submission that sleeps.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

from robolab.grading.wire import codec

if TYPE_CHECKING:
    pass


#: Without ``Limits.total_cpu_seconds`` / ``total_wall_seconds``, a submission (its loads
#: and calls together) may use this many per-call limits in total.
BUDGET_CALLS = 5
#: A lab whose hidden tests state ``REFERENCE_CPU_SECONDS`` (the CPU time the reference
#: solution's worker uses while graded) gives a submission this many times that in CPU
#: time, at least :data:`MIN_CPU_BUDGET_SECONDS` (never more than :data:`BUDGET_CALLS`
#: per-call limits): see :func:`reference_limits`. A correct solution 5x slower than the
#: reference fits with room to spare (CPU time itself grows a little on a busy machine).
BUDGET_FACTOR = 8.0
MIN_CPU_BUDGET_SECONDS = 20.0
#: The wall-time backstop of a submission with a reference: this many times its CPU budget,
#: at least :data:`MIN_BUDGET_SECONDS`, counted net of waiting for a CPU
#: (:class:`~robolab.grading.isolation.processes.AwakeClock`): it stops a submission that sleeps,
#: never one that computes or waits for a core.
WALL_FACTOR = 2.0
MIN_BUDGET_SECONDS = 60.0


#: Largest message accepted from a worker (a result, in pickled form): the codec's limit.
MAX_MESSAGE_BYTES = codec.LIMITS.max_bytes
#: Seconds a worker may take to start and isolate itself (before student code runs).
STARTUP_SECONDS = 30.0
#: How often a waiting grader checks the worker's CPU time and liveness.
POLL_SECONDS = 0.05


@dataclass
class Limits:
    """Resource limits of a worker.

    Attributes
    ----------
    cpu_seconds : float
        CPU time per call (and for loading the notebook), the processes it starts included.
    wall_seconds : float
        Wall-clock time per call (and for loading the notebook), a backstop against
        sleeping or stalled code: counted net of the time the worker (and the grader
        waiting for it) spent waiting for a CPU, so a busy machine never reaches it.
    memory_bytes : int
        Address space of the worker (RLIMIT_AS).
    max_processes : int
        Processes and threads of the worker's uid (RLIMIT_NPROC).
    max_output_bytes : int
        stdout + stderr kept per submission; the rest is counted and dropped.
    total_wall_seconds : float or None
        Wall-clock backstop of a whole submission (every load of the notebook and
        every call), counted like ``wall_seconds``; once spent, its remaining calls
        fail at once. None: :data:`BUDGET_CALLS` times ``wall_seconds``.
    total_cpu_seconds : float or None
        CPU time of a whole submission (every load and every call, the processes
        they start included): what decides "too slow". None: :data:`BUDGET_CALLS`
        times ``cpu_seconds``; a lab whose hidden tests state the reference's CPU
        time (``REFERENCE_CPU_SECONDS``) gets :func:`reference_limits` of it.
    """

    cpu_seconds: float = 30.0
    wall_seconds: float = 60.0
    memory_bytes: int = 2 * 2**30
    max_processes: int = 64
    max_output_bytes: int = 2**20
    total_wall_seconds: float | None = None
    total_cpu_seconds: float | None = None

    @property
    def budget_seconds(self) -> float:
        """The wall-time backstop of a whole submission (net of waiting for a CPU)."""
        if self.total_wall_seconds is not None:
            return self.total_wall_seconds
        return BUDGET_CALLS * self.wall_seconds

    @property
    def cpu_budget_seconds(self) -> float:
        """The CPU time of a whole submission: loads and calls, children included."""
        if self.total_cpu_seconds is not None:
            return self.total_cpu_seconds
        return BUDGET_CALLS * self.cpu_seconds


def reference_limits(limits: Limits, reference_cpu_seconds: float) -> Limits:
    """``limits`` with the totals a lab's reference CPU time gives (those not set already).

    CPU: ``max(MIN_CPU_BUDGET_SECONDS, BUDGET_FACTOR * reference_cpu_seconds)``; the wall
    backstop: ``max(MIN_BUDGET_SECONDS, WALL_FACTOR * cpu budget)``. Neither exceeds its
    default (``BUDGET_CALLS`` per-call limits). Both are charged with what the worker uses,
    measured as the reference was, so the grade does not depend on the machine's load.

    Raises
    ------
    ValueError
        When ``reference_cpu_seconds`` is not a positive number.
    """
    if not reference_cpu_seconds > 0:
        raise ValueError(f"reference_cpu_seconds must be > 0, got {reference_cpu_seconds!r}")
    cpu = limits.total_cpu_seconds
    if cpu is None:
        cpu = min(
            limits.cpu_budget_seconds,
            max(MIN_CPU_BUDGET_SECONDS, BUDGET_FACTOR * reference_cpu_seconds),
        )
    wall = limits.total_wall_seconds
    if wall is None:
        wall = min(limits.budget_seconds, max(MIN_BUDGET_SECONDS, WALL_FACTOR * cpu))
    return dataclasses.replace(limits, total_cpu_seconds=cpu, total_wall_seconds=wall)
