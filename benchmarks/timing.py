"""Shared timing for the benchmark scripts: one BLAS thread, one core, best of N runs.

Import this module *before numpy*: on import it sets ``OMP_NUM_THREADS``,
``OPENBLAS_NUM_THREADS`` and ``MKL_NUM_THREADS`` to 1 (unless already set), and
the BLAS libraries read them only when numpy loads them. The scripts are run as
``python benchmarks/<name>.py``, so ``benchmarks/`` is on ``sys.path`` and
``import timing`` finds this file::

    import timing  # before numpy

    # isort: split
    import numpy as np

    def main():
        pinned = timing.pin_to_one_core()  # "pinned to CPU 0"
        t = timing.best_of(fn, 5, *args)   # Timing(wall=..., cpu=...), seconds

``make bench`` runs every ``benchmarks/*.py``, this one included: run as a
script it prints one line and exits 0.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

#: ``ROBOLAB_BENCH_TINY=1``: every benchmark runs at its smallest sizes with one repeat, to
#: show that it still runs to the end (tests/test_benchmarks.py); its figures mean nothing.
TINY = os.environ.get("ROBOLAB_BENCH_TINY") == "1"


def sized(full, tiny):
    """``full``, or ``tiny`` under ``ROBOLAB_BENCH_TINY=1``."""
    return tiny if TINY else full

if "numpy" in sys.modules:
    warnings.warn(
        "timing imported after numpy: the thread variables come too late to take effect",
        stacklevel=2,
    )
for _var in THREAD_VARIABLES:
    os.environ.setdefault(_var, "1")


def pin_to_one_core() -> str:
    """Pin this process to the lowest CPU it may run on; a short description for a header."""
    if not hasattr(os, "sched_setaffinity"):
        return "not pinned (sched_setaffinity unavailable)"
    cpu = min(os.sched_getaffinity(0))
    try:
        os.sched_setaffinity(0, {cpu})
    except OSError as exc:
        return f"not pinned ({exc.strerror})"
    return f"pinned to CPU {cpu}"


def load_average() -> str:
    """The machine's 1, 5 and 15 minute load averages, for a header (the host is shared)."""
    if not hasattr(os, "getloadavg"):
        return "load average unavailable"
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f} {five:.2f} {fifteen:.2f} on {os.cpu_count()} CPUs"


@dataclass(frozen=True)
class Timing:
    """Best (minimum) wall-clock and process-CPU seconds over the repeats, each on its own."""

    wall: float
    cpu: float


def best_of(fn: Callable[..., Any], repeats: int, *args: Any, **kwargs: Any) -> Timing:
    """Call ``fn(*args, **kwargs)`` ``repeats`` times; the minimum wall and CPU time of a call.

    CPU time is ``time.process_time`` (all threads of this process, no sleep),
    the steadier figure on a shared machine.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    repeats = sized(repeats, 1)
    wall = cpu = float("inf")
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn(*args, **kwargs)
        c1, w1 = time.process_time(), time.perf_counter()
        wall, cpu = min(wall, w1 - w0), min(cpu, c1 - c0)
    return Timing(wall, cpu)


def interleaved(fns: dict, repeats: int, before=None) -> dict:
    """Best process-CPU seconds of each function of ``fns``, calling them in turn each round.

    Interleaving (one call of every contender per round, ``repeats`` rounds) gives
    each the same share of the machine's noise, so their ratios are fair on a shared host.
    ``before(fn)``, when given, runs untimed before each timed call: :func:`flush_caches`
    (every contender starts from cold caches) or ``lambda fn: fn()`` (every contender
    finds its own data in the caches), so that no contender inherits the caches of the
    one called before it.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    repeats = sized(repeats, 1)
    best = dict.fromkeys(fns, float("inf"))
    for _ in range(repeats):
        for key, fn in fns.items():
            if before is not None:
                before(fn)
            c0 = time.process_time()
            fn()
            best[key] = min(best[key], time.process_time() - c0)
    return best


_FLUSH: list = []


def flush_caches(_fn=None) -> None:
    """Evict this core's caches and the shared last-level cache: read and write 64 MiB."""
    import numpy as np

    if not _FLUSH:
        _FLUSH.append(np.ones(64 << 17))  # 64 MiB of float64, twice this machine's L3
    junk = _FLUSH[0]
    junk[::8] += junk.sum() * 0.0  # a read of every line, then a write of every line


if __name__ == "__main__":
    print("benchmarks/timing.py: shared timing helpers for the other benchmarks (nothing to run)")
