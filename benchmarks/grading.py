"""How fast the autograder grades: one submission, and a batch of 50 with -j 2.

Targets (issue 4, "Speed"): one submission of one lab <= 5 s; 50 submissions
with -j 2 <= 2 minutes on a 2-core machine. The baseline is the same hidden
tests run on the reference solutions, without a worker, in one pytest process.

    python benchmarks/grading.py [--batch 50] [--jobs 2]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from robolab.grading.labs import find_lab
from robolab.grading.runner import grade_all, grade_submission

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples" / "submissions" / "demo"


def _baseline() -> float:
    lab = find_lab("demo")
    start = time.perf_counter()
    # the runner's pytest invocation minus the notebook: isolation costs the difference
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            str(lab.hidden_tests),
            "-q",
            "-p",
            "no:cacheprovider",
            "-p",
            "robolab.grading.pytest_plugin",
        ],
        cwd=REPO,
        check=True,
        capture_output=True,
        env=dict(os.environ, PYTEST_DISABLE_PLUGIN_AUTOLOAD="1"),
    )
    return time.perf_counter() - start


def _one(repeats: int) -> tuple[float, float]:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = grade_submission(EXAMPLES / "correct.ipynb")
        times.append(time.perf_counter() - start)
        if result.total != 100:
            raise SystemExit(
                f"the correct demo submission scored {result.total}, not 100: {result.errors}"
            )
    return statistics.median(times), max(times)


def _batch(n: int, jobs: int) -> tuple[float, int]:
    sources = sorted(EXAMPLES.glob("*.ipynb"))
    with tempfile.TemporaryDirectory(prefix="robolab-bench-") as tmp:
        paths = []
        for i in range(n):
            path = Path(tmp) / f"student{i:03d}.ipynb"
            shutil.copy(sources[i % len(sources)], path)
            paths.append(path)
        start = time.perf_counter()
        results = grade_all(paths, jobs=jobs, progress=False)
        seconds = time.perf_counter() - start
    return seconds, sum(1 for r in results if r.errors)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--batch", type=int, default=50)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)

    base = _baseline()
    median, worst = _one(args.repeats)
    batch, errors = _batch(args.batch, args.jobs)
    rows = [
        ("baseline: demo hidden tests on the reference solutions (no worker)", base, None),
        (
            f"one demo submission graded (median of {args.repeats}; worst {worst:.2f} s)",
            median,
            5.0,
        ),
        (
            f"{args.batch} demo submissions graded with -j {args.jobs} ({errors} with errors)",
            batch,
            120.0,
        ),
    ]
    width = max(len(r[0]) for r in rows)
    print(f"{'case'.ljust(width)}  {'seconds':>8}  {'target':>7}  ok")
    print(f"{'-' * width}  {'-' * 8}  {'-' * 7}  --")
    failed = False
    for name, seconds, target in rows:
        shown = " " * 7 if target is None else f"{target:7.0f}"
        ok = "" if target is None else ("yes" if seconds <= target else "NO")
        failed |= ok == "NO"
        print(f"{name.ljust(width)}  {seconds:8.2f}  {shown}  {ok}")
    print(f"\nper submission in the batch: {batch / args.batch:.2f} s")
    return 1 if failed or errors else 0


if __name__ == "__main__":
    sys.exit(main())
