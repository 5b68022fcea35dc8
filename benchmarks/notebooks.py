"""Kernel CPU time of every solved lab notebook, against the 20 s budget of a lab.

Runs ``robolab solve`` into a temporary folder, executes each solved notebook with
nbclient (Jupyter's own executor) and reads the kernel's own CPU time
(``resource.getrusage`` in a last cell): the budget is for the student's kernel, so
start-up of the client and wall time lost to a busy machine do not count. Prints one
row per lab with the slowest cells, and the machine's load.

    python benchmarks/notebooks.py [LAB ...] [--cells N]

``LAB``: part of a notebook's name (``mcl``, ``05``); default every lab. The first run
after an edit of a numba kernel (or in a fresh checkout) includes its compilation into
numba's cache; run twice to see what a student's later runs cost.

Under ``ROBOLAB_BENCH_TINY=1`` (tests/test_benchmarks.py) only lab 01 (Bayes, the quickest)
is solved and run: the same path, one notebook.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TINY = os.environ.get("ROBOLAB_BENCH_TINY") == "1"
BUDGET = 20.0  # seconds of kernel CPU per solved notebook (issue: each lab <= 20 s)
CPU_CELL = ("import resource as _r; _u = _r.getrusage(_r.RUSAGE_SELF); "
            "print('CPU', _u.ru_utime + _u.ru_stime)")
TIMER = ("import time as _t, resource as _r\n"
         "def _cpu():\n    u = _r.getrusage(_r.RUSAGE_SELF); return u.ru_utime + u.ru_stime\n"
         "_cells = []\n"
         "def _pre(*a):\n    global _c0\n    _c0 = _cpu()\n"
         "def _post(result):\n"
         "    cell = (result.info.raw_cell or '').strip().splitlines()[:1]\n"
         "    _cells.append((_cpu() - _c0, cell))\n"
         "get_ipython().events.register('pre_run_cell', _pre)\n"
         "get_ipython().events.register('post_run_cell', _post)")
REPORT = ("import json as _j; print('CELLS', _j.dumps(sorted(_cells, reverse=True)[:{cells}]))\n"
          + CPU_CELL)


def run(notebook: Path, cells: int = 3) -> tuple[float, list, float]:
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(str(notebook), as_version=4)
    nb.cells.insert(0, nbformat.v4.new_code_cell(TIMER))
    nb.cells.append(nbformat.v4.new_code_cell(REPORT.replace("{cells}", str(cells))))
    start = time.perf_counter()
    NotebookClient(nb, timeout=900, kernel_name="python3",
                   resources={"metadata": {"path": str(notebook.parent)}}).execute()
    wall = time.perf_counter() - start
    text = "".join(o.get("text", "") for o in nb.cells[-1].outputs if o.get("name") == "stdout")
    cpu = float(text.split("CPU", 1)[1].split()[0])
    cells = json.loads(text.split("CELLS", 1)[1].split("\n", 1)[0])
    return cpu, cells, wall


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("labs", nargs="*", help="parts of notebook names (default: every lab)")
    p.add_argument("--cells", type=int, default=3, help="how many of the slowest cells to name")
    args = p.parse_args()
    os.environ.setdefault("MPLBACKEND", "Agg")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "solved"
        source = ROOT / "notebooks" / "01_bayes.ipynb" if TINY else ROOT / "notebooks"
        if TINY:
            out.mkdir()
        target = out / source.name if TINY else out
        subprocess.run([sys.executable, "-m", "robolab.cli", "solve", str(source),
                        "-o", str(target)], check=True, capture_output=True)
        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; "
              f"budget {BUDGET:g} s of kernel CPU per lab")
        print(f"{'lab':<24}{'kernel CPU [s]':>16}{'of budget':>11}{'wall [s]':>10}  slowest cells")
        over = 0
        for nb in sorted(out.glob("*.ipynb")):
            if args.labs and not any(lab in nb.stem for lab in args.labs):
                continue
            cpu, cells, wall = run(nb, args.cells)
            over += cpu > BUDGET
            slow = "; ".join(f"{c:.1f} s {(line or [''])[0][:40]!r}" for c, line in cells)
            print(f"{nb.stem:<24}{cpu:>16.1f}{cpu / BUDGET:>10.0%}{wall:>10.1f}  {slow}")
        print(f"{over} lab(s) over budget")
    return 0


if __name__ == "__main__":
    sys.exit(main())
