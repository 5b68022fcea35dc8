"""Throughput of sharded grading: CPU seconds per submission of each lab, and N shards as
N processes against one unsharded run of the same batch.

For each lab the batch is ``--copies`` copies of each of its example submissions
(correct, partial, wrong), graded by ``robolab grade --out NEW -j 1`` in a fresh process;
CPU seconds are those of that process and everything it started (``RUSAGE_CHILDREN``),
so they hold on a loaded machine where wall seconds do not. Then the whole mixed batch
is graded once unsharded (``-j 1``) and as ``--shards`` processes (``--shard K/N``, each
``-j 1``), merged, and the merged gradebook compared with the unsharded one row by row.

The last lines are what 1 000 submissions cost: core-hours at the measured CPU seconds
per submission (the mean over the labs measured) and, for a price per core-hour given
with ``--price`` (default 0.05 USD, about an on-demand cloud vCPU), its price.

    python benchmarks/shards.py [--labs bayes beam_model mcl] [--copies 2] [--shards 2]
        [--price 0.05]

Under ``ROBOLAB_BENCH_TINY=1`` (tests/test_benchmarks.py) the defaults shrink to the demo
lab, one copy of each example: every step (per-lab run, unsharded run, shards, merge,
comparison) still runs.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from robolab.grading.course.report import without_measured

REPO = Path(__file__).resolve().parents[1]
ROBOLAB = [sys.executable, "-m", "robolab.cli"]
TINY = os.environ.get("ROBOLAB_BENCH_TINY") == "1"


def _run(args: list[str], cwd: Path) -> tuple[float, float]:
    """Wall and CPU seconds of ``robolab ARGS`` (a fresh process and all it started)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    subprocess.run([*ROBOLAB, *args], cwd=cwd, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return time.monotonic() - started, cpu


def _batch(folder: Path, labs: list[str], copies: int) -> dict[str, list[str]]:
    """Copies of every example submission of ``labs`` in ``folder``; names by lab."""
    names: dict[str, list[str]] = {}
    for lab in labs:
        for example in sorted((REPO / "examples" / "submissions" / lab).glob("*.ipynb")):
            for c in range(copies):
                name = f"s{c}_{example.stem}_{lab}.ipynb"
                shutil.copy(example, folder / name)
                names.setdefault(lab, []).append(name)
    return names


def _rows(folder: Path) -> list[dict]:
    rows = json.loads((folder / "gradebook.json").read_text())
    return without_measured(rows)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--labs", nargs="+", default=["demo"] if TINY else ["bayes", "beam_model", "mcl"]
    )
    p.add_argument("--copies", type=int, default=1 if TINY else 2)
    p.add_argument("--shards", type=int, default=2)
    p.add_argument("--price", type=float, default=0.05, help="USD per core-hour")
    args = p.parse_args()
    print(f"load before: {os.getloadavg()}; {os.cpu_count()} cores")
    per_submission = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        print(f"{'lab':<12} {'submissions':>11} {'wall s':>7} {'CPU s':>7} {'CPU s/sub':>9}")
        for lab in args.labs:
            folder = tmp / lab
            folder.mkdir()
            names = _batch(folder, [lab], args.copies)[lab]
            wall, cpu = _run(["grade", *names, "--out", "out", "-j", "1"], folder)
            per_submission[lab] = cpu / len(names)
            print(f"{lab:<12} {len(names):>11} {wall:7.1f} {cpu:7.1f} {cpu / len(names):9.2f}")
        mixed = tmp / "mixed"
        mixed.mkdir()
        names = [n for ns in _batch(mixed, args.labs, args.copies).values() for n in ns]
        wall1, cpu1 = _run(["grade", *names, "--out", "whole", "-j", "1"], mixed)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.monotonic()
        procs = [
            subprocess.Popen(
                [
                    *ROBOLAB,
                    "grade",
                    *names,
                    "--shard",
                    f"{k}/{args.shards}",
                    "--out",
                    f"shard-{k}",
                    "-j",
                    "1",
                ],
                cwd=mixed,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            for k in range(1, args.shards + 1)
        ]
        for proc in procs:
            if proc.wait() != 0:
                raise SystemExit("a shard failed")
        wall_n = time.monotonic() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu_n = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
        _run(
            ["merge", *(f"shard-{k}" for k in range(1, args.shards + 1)), "--out", "merged"], mixed
        )
        same = _rows(mixed / "whole") == _rows(mixed / "merged")
        print(
            f"\nmixed batch of {len(names)}: unsharded -j 1 {wall1:.1f} s wall, {cpu1:.1f} s CPU; "
            f"{args.shards} shards as {args.shards} processes {wall_n:.1f} s wall, {cpu_n:.1f} s "
            f"CPU; speed-up {wall1 / wall_n:.2f}x on {os.cpu_count()} cores; merged rows "
            f"{'equal' if same else 'DIFFER from'} the unsharded run"
        )
    mean = sum(per_submission.values()) / len(per_submission)
    hours = 1000 * mean / 3600
    print(
        f"1 000 submissions (the mean of {', '.join(per_submission)}: {mean:.2f} CPU s each): "
        f"{hours:.2f} core-hours, {hours * args.price:.2f} USD at {args.price} USD/core-hour"
    )
    print(f"load after: {os.getloadavg()}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
