"""How fast ``robolab similarity`` compares a class: hundreds of Bayes-lab notebooks.

The class is ``--students`` notebooks made from two genuinely different implementations
(the ones of tests/grading/course/test_similarity.py), each student's copy disguised or not and
given a line of its own in every function, so that no two are identical. The baseline,
in the same run, is copydetect's own way: ``compare_files`` on every pair, timed on the
first ``--baseline`` students and scaled by the number of pairs.

    python benchmarks/similarity.py [--students 300] [--baseline 40]
"""

from __future__ import annotations

import argparse
import ast
import os
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
#: ``ROBOLAB_BENCH_TINY=1`` (tests/test_benchmarks.py): a class of 12, a baseline of 6.
TINY = os.environ.get("ROBOLAB_BENCH_TINY") == "1"

from robolab.grading.course.similarity import compare, fragments, similarity_report  # noqa: E402
from tests.grading.course.test_similarity import LOOPS, VECTORIZED, disguise, notebook  # noqa: E402


def _own_line(code: str, i: int) -> str:
    """``code`` with a statement of student ``i``'s own at the top of every function."""
    tree = ast.parse(code)
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            node.body.insert(0, ast.parse(f"student_{i} = {i} * {i % 7}").body[0])
    return ast.unparse(tree)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--students", type=int, default=12 if TINY else 300)
    p.add_argument("--baseline", type=int, default=6 if TINY else 40)
    args = p.parse_args()
    print(f"load before: {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for i in range(args.students):
            base = (VECTORIZED, LOOPS)[i % 2]
            code = _own_line(disguise(base) if i % 3 else base, i)
            paths.append(notebook(Path(tmp) / f"student{i:04d}.ipynb", code))
        started = time.perf_counter()
        found = fragments(paths)
        t_fragments = time.perf_counter() - started
        started = time.perf_counter()
        pairs = compare(found)
        t_compare = time.perf_counter() - started
        started, cpu = time.perf_counter(), time.process_time()
        similarity_report(paths, Path(tmp) / "out")
        t_report = time.perf_counter() - started
        cpu_report = time.process_time() - cpu

        from copydetect import compare_files

        sub = [f for f in found if f.submission < f"student{args.baseline:04d}"]
        started = time.perf_counter()
        for i, a in enumerate(sub):
            for b in sub[i + 1 :]:
                if a.exercise == b.exercise:
                    compare_files(a.fingerprint, b.fingerprint)
        t_pairwise = time.perf_counter() - started
    n, m = args.students, args.baseline
    scaled = t_pairwise * (n * (n - 1)) / (m * (m - 1))
    print(
        f"{n} students, {len(found)} fragments, {len(pairs)} pairs: fingerprints "
        f"{t_fragments:.2f} s, all pairs {t_compare:.2f} s; the whole command (CSV, HTML) "
        f"{t_report:.2f} s wall, {cpu_report:.2f} s CPU"
    )
    print(
        f"copydetect's compare_files on every pair: {t_pairwise:.2f} s for {m} students, "
        f"about {scaled:.0f} s for {n}: the sparse product is {scaled / t_compare:.0f}x faster"
    )
    print(f"load after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
