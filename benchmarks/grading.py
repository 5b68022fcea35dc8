"""How fast the autograder grades: one submission, and a batch with -j 2; cold vs warm workers.

Targets: one submission of the bayes lab <= 1 s (issue 19, item 4); 50 submissions
with -j 2 <= 7 s on a 2-core machine (issue 29; was 45 s in issue 19), scaled to
``--batch``. Every case runs twice in the same session, interleaved, best of the repeats:

- cold: ``ROBOLAB_WARM_WORKERS=0``, every worker a fresh ``python -m
  robolab.grading.isolation.worker`` that imports numpy and the notebook's libraries itself
  (the grader before the warm zygote);
- warm: workers forked by one zygote (:mod:`robolab.grading.isolation.zygote`) per grading
  session.

"one submission (CLI)" is ``robolab grade one.ipynb --out NEW_FOLDER`` in a fresh process:
what an instructor waits for, zygote start-up included. "one submission (warm)" is
``grade_submission`` in a process whose zygote already runs (a submission in a
batch). The machine's load average is printed before and after: on a shared
machine, read the ratios, not the seconds.

    python benchmarks/grading.py [--lab bayes] [--batch 50] [--jobs 2] [--repeats 3]

A missed target is shown (``NO`` in the last column) but does not fail the run: on a
shared machine the seconds depend on the load. The exit status is 1 only when a graded
run had errors (the grader is broken). Under ``ROBOLAB_BENCH_TINY=1``
(tests/test_benchmarks.py) the defaults shrink to the demo lab, a batch of 2 and one
repeat: every case, cold and warm, still runs.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from robolab.grading.isolation import warm
from robolab.grading.running.runner import grade_all, grade_submission

REPO = Path(__file__).resolve().parents[1]
TINY = os.environ.get("ROBOLAB_BENCH_TINY") == "1"
MODES = ("cold", "warm")


def _set_mode(mode: str) -> None:
    """Switch this process (and the pytest runs it starts) to cold or warm workers."""
    warm.reset_shared(None)
    if mode == "cold":
        os.environ[warm.SWITCH_VARIABLE] = "0"
    else:
        os.environ.pop(warm.SWITCH_VARIABLE, None)


def _submissions(lab: str) -> list[Path]:
    found = sorted((REPO / "examples" / "submissions" / lab).glob("*.ipynb"))
    if not found:
        raise SystemExit(f"no example submissions for lab {lab!r}")
    return found


def _correct(lab: str) -> Path:
    return REPO / "examples" / "submissions" / lab / "correct.ipynb"


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _cli(lab: str, tmp: Path) -> tuple[float, float | None]:
    # A fresh output folder every time: in a folder that already holds the grade, robolab
    # grade keeps it and grades nothing (the batch state), which is not what is measured.
    out = Path(tempfile.mkdtemp(prefix="cli-", dir=tmp))
    start, cpu = time.perf_counter(), _children_cpu()
    subprocess.run(
        [sys.executable, "-m", "robolab.cli", "grade", str(_correct(lab)), "--out", str(out)],
        check=True,
        capture_output=True,
        cwd=REPO,
    )
    return time.perf_counter() - start, _children_cpu() - cpu


def _warm_one(lab: str) -> tuple[float, float | None]:
    grade_submission(_correct(lab))  # starts the zygotes (in warm mode) and warms the caches
    start = time.perf_counter()
    result = grade_submission(_correct(lab))
    seconds = time.perf_counter() - start
    if result.errors or result.total != result.max_points:
        raise SystemExit(f"the correct {lab} submission scored {result.total}: {result.errors}")
    return seconds, None  # its processes are children of the zygotes: not counted here


def _batch(lab: str, n: int, jobs: int, tmp: Path) -> tuple[float, float, int]:
    sources = _submissions(lab)
    folder = tmp / "batch"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    paths = []
    for i in range(n):
        path = folder / f"student{i:03d}.ipynb"
        shutil.copy(sources[i % len(sources)], path)
        paths.append(path)
    warm.reset_shared(None)
    start, cpu = time.perf_counter(), _children_cpu()
    results = grade_all(paths, jobs=jobs, progress=False)
    seconds = time.perf_counter() - start
    warm.reset_shared(None)  # a batch is one grading session: its zygotes go with it
    return seconds, _children_cpu() - cpu, sum(1 for r in results if r.errors)


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min) on {os.cpu_count()} CPUs"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--lab", default="demo" if TINY else "bayes")
    p.add_argument("--batch", type=int, default=2 if TINY else 50)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument(
        "--repeats", type=int, default=1 if TINY else 3, help="interleaved repeats of each case"
    )
    args = p.parse_args(argv)

    print(f"before: {_load()}")
    best: dict[tuple[str, str], float] = {}
    best_cpu: dict[tuple[str, str], float] = {}
    errors = 0
    with tempfile.TemporaryDirectory(prefix="robolab-bench-") as tmp:
        cases: list[tuple[str, Callable[[], tuple[float, float | None]]]] = [
            ("one submission (CLI)", lambda: _cli(args.lab, Path(tmp))),
            ("one submission (warm)", lambda: _warm_one(args.lab)),
        ]

        def batch() -> tuple[float, float]:
            nonlocal errors
            seconds, cpu, failed = _batch(args.lab, args.batch, args.jobs, Path(tmp))
            errors += failed
            return seconds, cpu

        cases.append((f"{args.batch} submissions, -j {args.jobs}", batch))
        for repeat in range(args.repeats):
            for name, run in cases:
                # Alternate which mode goes first, so a load spike does not favour one.
                for mode in MODES if repeat % 2 == 0 else MODES[::-1]:
                    _set_mode(mode)
                    seconds, cpu = run()
                    shown = "" if cpu is None else f", CPU {cpu:.2f} s"
                    print(
                        f"  repeat {repeat + 1}, {name}, {mode}: {seconds:.2f} s{shown}", flush=True
                    )
                    best[name, mode] = min(best.get((name, mode), float("inf")), seconds)
                    if cpu is not None:
                        best_cpu[name, mode] = min(best_cpu.get((name, mode), float("inf")), cpu)
        _set_mode("warm")
    print(f"after:  {_load()}\n")

    targets = {cases[0][0]: 1.0, cases[1][0]: 1.0, cases[2][0]: 7.0 * args.batch / 50}
    width = max(len(name) for name, _ in cases)
    print(
        f"{'case (' + args.lab + ')':<{width}}  {'cold s':>7}  {'warm s':>7}  {'speed-up':>8}  "
        f"{'CPU cold':>8}  {'CPU warm':>8}  {'target':>6}  ok"
    )
    missed = 0
    for name, _ in cases:
        cold, warm = best[name, "cold"], best[name, "warm"]
        cpu = [best_cpu.get((name, mode)) for mode in MODES]
        shown = [" " * 8 if c is None else f"{c:8.2f}" for c in cpu]
        ok = warm <= targets[name]
        missed += not ok
        print(
            f"{name:<{width}}  {cold:7.2f}  {warm:7.2f}  {cold / warm:7.2f}x  "
            f"{shown[0]}  {shown[1]}  {targets[name]:6.1f}  {'yes' if ok else 'NO'}"
        )
    print(
        f"\nseconds: wall clock, best of {args.repeats} interleaved repeats; CPU: every process "
        f"of the case (grader, pytest runs, zygotes, workers); {errors} graded runs had errors"
    )
    if missed:
        print(f"{missed} target(s) missed (read the load average above)")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
