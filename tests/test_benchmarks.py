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
NEEDS_SHARED = {"raycast"}
#: Benchmarks that are whole grading pipelines of their own (minutes even at their
#: smallest), exercised elsewhere in the suite: grading.py grades with the CLI
#: (tests/grading), notebooks.py runs every solved notebook (make test's nbval run),
#: shards.py shards and merges (tests/grading/course/test_shards.py), load.py grades beside
#: busy loops (tests/grading/running/test_load.py), gradescope_memory.py installs and runs
#: bundles (tests/grading/exports/test_gradescope_bundle.py), install.py a fresh venv.
ELSEWHERE = {"grading", "notebooks", "shards", "load", "gradescope_memory", "install"}


@pytest.mark.slow
@pytest.mark.parametrize("path", BENCHMARKS, ids=lambda p: p.stem)
def test_the_benchmark_runs_to_the_end(path):
    if path.stem in ELSEWHERE:
        pytest.skip(f"{path.name} is exercised by its own tests")
    if path.stem in NEEDS_SHARED and not (ROOT.parent / "shared" / "data").is_dir():
        pytest.skip("needs ../shared/data")
    env = {**os.environ, "ROBOLAB_BENCH_TINY": "1", "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [sys.executable, str(path)], cwd=ROOT, env=env, capture_output=True, text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    assert proc.stdout.strip(), "a benchmark prints its table"
