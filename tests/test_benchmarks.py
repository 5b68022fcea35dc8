"""Every benchmark runs to the end: each one at its tiny size (ROBOLAB_BENCH_TINY=1).

``make bench`` must exit 0; a benchmark that broke (a renamed private helper, a changed
return value, a missing data folder) fails here instead of the next time someone
measures. The figures of a tiny run mean nothing and are not read.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = sorted((ROOT / "benchmarks").glob("*.py"))
#: Benchmarks that read ../shared/data (they fail without it, as they should).
NEEDS_SHARED = {"raycast", "graph_slam"}
#: Benchmarks that need the network even at their tiny size (skipped here, with the reason).
NEEDS_NETWORK = {
    "gradescope_memory": "gradescope_memory.py runs the bundle's own setup.sh, which "
    "pip-installs robolab's dependencies (numpy, scipy, matplotlib, ...) from PyPI into a "
    "fresh venv: it needs the network, which the test suite does not use",
}


@pytest.mark.slow
@pytest.mark.parametrize("path", BENCHMARKS, ids=lambda p: p.stem)
def test_the_benchmark_runs_to_the_end(path):
    if path.stem in NEEDS_NETWORK:
        pytest.skip(NEEDS_NETWORK[path.stem])
    if path.stem in NEEDS_SHARED and not (ROOT.parent / "shared" / "data").is_dir():
        pytest.skip("needs ../shared/data")
    env = {**os.environ, "ROBOLAB_BENCH_TINY": "1", "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [sys.executable, str(path)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    assert proc.stdout.strip(), "a benchmark prints its table"
