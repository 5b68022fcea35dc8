"""A student's first minutes: installing the student edition, then the first and second check.

Builds the student edition's wheel (``robolab release``), installs it into a fresh venv
(``pip install robolab-*.whl``: only what the labs import, no test stack; pip's cache
makes the download part depend on the machine, so the row says what it measured), then
runs ``robolab check`` twice on a solved copy of a lab: the first check pays the
one-time costs (bytecode, matplotlib's font cache, numba's kernels compiled into their
cache), the second is what every later check costs. Wall and CPU seconds (children
included), with the machine's load.

    python benchmarks/install.py [--lab mcl] [--here]

``--here`` skips the wheel and the install: both checks run with this Python (this
checkout's robolab), still with empty numba and matplotlib caches, which is what the
first check of a fresh install pays beyond the bytecode.

Under ``ROBOLAB_BENCH_TINY=1`` the install is skipped and both checks run in this
environment on the bayes lab (tests/test_benchmarks.py).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import timing

ROOT = Path(__file__).resolve().parents[1]


def timed(cmd: list[str], **kw) -> tuple[float, float]:
    """Wall and CPU seconds (of the children) of one command, which must succeed."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, **kw)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 1):  # check exits 1 when a visible check fails
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--lab", default="mcl", help="the lab whose solved notebook is checked")
    p.add_argument("--here", action="store_true",
                   help="no install: check with this Python, from empty numba/matplotlib caches")
    args = p.parse_args()
    lab = "bayes" if timing.TINY else args.lab
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        python = Path(sys.executable)
        env = dict(os.environ, MPLBACKEND="Agg")
        if not timing.TINY and not args.here:
            edition = tmp / "edition"
            subprocess.run([sys.executable, "-m", "robolab.cli", "release", str(edition)],
                           check=True, capture_output=True)
            wheel = next((edition / "dist").glob("robolab-*.whl"))
            subprocess.run([sys.executable, "-m", "venv", str(tmp / "venv")], check=True)
            python = tmp / "venv" / "bin" / "python"
            rows.append(("pip install the student wheel (pip cache as found)",
                         *timed([str(python), "-m", "pip", "install", "--quiet", str(wheel)])))
        if not timing.TINY:
            # a fresh user's caches: matplotlib's font list and numba's kernels start empty
            env.update(MPLCONFIGDIR=str(tmp / "mpl"), NUMBA_CACHE_DIR=str(tmp / "numba"))
        notebook = next((ROOT / "notebooks").glob(f"[0-9][0-9]_{lab}.ipynb"))
        solved = tmp / notebook.name
        subprocess.run([sys.executable, "-m", "robolab.cli", "solve", str(notebook),
                        "-o", str(solved)], check=True, capture_output=True)
        check = [str(python), "-m", "robolab.cli", "check", str(solved)]
        rows.append((f"first robolab check ({lab}, solved)", *timed(check, env=env, cwd=tmp)))
        rows.append((f"second robolab check ({lab}, solved)", *timed(check, env=env, cwd=tmp)))
    print(f"{timing.load_average()}")
    print(f"{'step':58s} {'wall s':>8s} {'CPU s':>8s}")
    for name, wall, cpu in rows:
        print(f"{name:58s} {wall:8.1f} {cpu:8.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
