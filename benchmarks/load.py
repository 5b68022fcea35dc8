"""The same grade at any load: grades alone and with -j 8 beside a busy loop on every core.

Grades the correct example of every lab and an MCL solution three times slower than the
reference in CPU (built as ``tests/grading/running/test_load.py`` builds it) twice in one
run: alone with ``-j 2``, then with ``-j 8`` beside one busy loop per core (each in a
session of its own, as independent programs). Prints, per submission, the score of
both runs, the CPU time of its worker (what the budgets count) against its budget, the
wall time of both runs, and anything flagged; then the machine's load. The grades must
be equal; the wall times show what the machine did, and are not graded.

    python benchmarks/load.py [--jobs 8]
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # the test module that builds the slow solution

from robolab.grading.running.proxy import Limits, reference_limits  # noqa: E402
from robolab.grading.running.runner import grade_all  # noqa: E402
from tests.grading.running.test_load import (  # noqa: E402
    busy_loops_running,
    three_times_slower,
)


def _budget(lab: str) -> float:
    module = importlib.import_module(f"tests.labs.test_{lab}")
    limits = Limits(**getattr(module, "GRADING_LIMITS", {}))
    return reference_limits(limits, module.REFERENCE_CPU_SECONDS).cpu_budget_seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=8)
    args = parser.parse_args()
    examples = REPO / "examples" / "submissions"
    with tempfile.TemporaryDirectory() as tmp:
        # ROBOLAB_BENCH_TINY=1 (tests/test_benchmarks.py): the demo lab only.
        slow = "demo" if os.environ.get("ROBOLAB_BENCH_TINY") == "1" else "mcl"
        paths = sorted(examples.glob(f"{'demo' if slow == 'demo' else '*'}/correct.ipynb"))
        paths.append(three_times_slower(examples / slow / "correct.ipynb", Path(tmp) / "s.ipynb"))
        names = [p.parent.name for p in paths[:-1]] + [f"{slow} 3x slower"]
        labs = [p.parent.name for p in paths[:-1]] + [slow]
        before = os.getloadavg()[0]
        alone = grade_all(paths, labs=labs, names=names, jobs=2, progress=False)
        between = os.getloadavg()[0]
        with busy_loops_running():
            loaded = grade_all(paths, labs=labs, names=names, jobs=args.jobs, progress=False)
        after = os.getloadavg()[0]
    print(
        f"| submission | score alone | score beside busy loops (-j {args.jobs}) "
        "| worker CPU / budget (s) | wall alone / loaded (s) | flagged |"
    )
    print("|---|---|---|---|---|---|")
    for a, b, lab in zip(alone, loaded, labs, strict=True):
        print(
            f"| {a.name} | {a.total:g}/{a.max_points:g} | {b.total:g}/{b.max_points:g} "
            f"| {a.cpu_seconds:.1f}, {b.cpu_seconds:.1f} / {_budget(lab):g} "
            f"| {a.seconds:.0f} / {b.seconds:.0f} | {'; '.join(b.limits) or '-'} |"
        )
    same = all(
        a.exercise_scores() == b.exercise_scores() for a, b in zip(alone, loaded, strict=True)
    )
    print(
        f"\nsame grades: {same}; load average {before:.1f} before, {between:.1f} after the "
        f"run alone, {after:.1f} after the run beside busy loops ({os.cpu_count()} CPUs)"
    )
    if not same:
        raise SystemExit("the grades differ: a grade depends on the machine's load")


if __name__ == "__main__":
    main()
