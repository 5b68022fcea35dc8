"""The same grade at any load, and a batch that stops when asked, beside busy loops.

Busy loops run on every core the tests may use, each in a session of its own (as
independent programs: Linux shares the CPU per session), while submissions are graded
with more jobs than cores. Nothing here asserts how long anything took; a bound only
catches a hang.
"""

from __future__ import annotations

import ast
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robolab.grading.running.runner import grade_all
from tests.grading.sigint import sigint_default

REPO = Path(__file__).resolve().parents[3]
EXAMPLES = REPO / "examples" / "submissions"
#: Seconds that only a hang exceeds (a stopped batch, a graded batch on a loaded machine).
HANG = 900


@contextlib.contextmanager
def busy_loops_running():
    """One busy loop per core, each in its own session (as independent programs)."""
    loops = []
    try:
        for cpu in sorted(os.sched_getaffinity(0)):
            proc = subprocess.Popen(
                [sys.executable, "-c", "while True: pass"],
                start_new_session=True,
                stdin=subprocess.DEVNULL,
            )
            loops.append(proc)
            os.sched_setaffinity(proc.pid, {cpu})
        yield loops
    finally:
        for proc in loops:
            proc.kill()
            proc.wait()


@pytest.fixture
def busy_loops():
    with busy_loops_running() as loops:
        yield loops


def _exercises(notebook: dict) -> list[str]:
    """The functions the notebook's exercise cells define."""
    names = []
    for cell in notebook["cells"]:
        if cell["cell_type"] == "code" and "exercise" in cell.get("metadata", {}).get("tags", []):
            tree = ast.parse("".join(cell["source"]))
            names += [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    return names


SLOWER = '''
import functools as _functools
import time as _time

_DEPTH = [0]


def _slower(function):
    """The same results for four times the CPU time (counted at the outermost call)."""

    @_functools.wraps(function)
    def slower(*args, **kwargs):
        start = _time.process_time()
        _DEPTH[0] += 1
        try:
            return function(*args, **kwargs)
        finally:
            _DEPTH[0] -= 1
            if _DEPTH[0] == 0:
                spent = _time.process_time() - start
                while _time.process_time() - start < 4 * spent:
                    pass

    return slower
'''


def three_times_slower(source: Path, target: Path) -> Path:
    """A copy of a correct notebook whose worker takes about three times the CPU time.

    Its exercises take four times theirs: loading the notebook and moving arguments and
    results cost the same as before (measured on MCL: 12.2 s of worker CPU, of which
    8 s in the exercises; 3x on the exercises alone gave 2.3x in all).
    """
    notebook = json.loads(source.read_text())
    names = _exercises(notebook)
    assert names, f"{source} has no exercise cells"
    code = SLOWER + "".join(f"\n{n} = _slower({n})" for n in names)
    notebook["cells"].append(
        {
            "cell_type": "code",
            "execution_count": None,
            "metadata": {},
            "outputs": [],
            "source": code.splitlines(keepends=True),
        }
    )
    target.write_text(json.dumps(notebook))
    return target


def _grades(results) -> dict[str, tuple]:
    return {r.name: (r.exercise_scores(), r.limits, r.errors) for r in results}


#: Graded alone too (-j 2), to compare with their grades under load: the cheapest lab, the
#: costliest (MCL) and the MCL solution three times slower. One notebook per class of cost
#: is what the comparison needs: every lab is graded under load below, where each must
#: earn full marks with nothing flagged, which no grading alone can exceed; that each
#: lab's solution earns full marks alone is the mutation suite's (tests/labs/mutants/, the
#: solved notebook of every lab, -j 2). Grading all ten labs alone as well doubled the
#: cost of this test (the costliest of the suite) and checked nothing more about load.
ALONE_TOO = ("demo", "mcl", "mcl_slow")


@pytest.mark.slow
def test_the_same_grades_beside_busy_loops(tmp_path, request):
    """Every lab's correct example and an MCL solution 3x slower than the reference (in
    CPU) earn full marks with -j 8 beside busy loops, nothing flagged; the cheapest lab,
    MCL and the slower MCL get the same grades there as alone."""
    paths = sorted(EXAMPLES.glob("*/correct.ipynb"))
    assert len(paths) >= 9
    slow = three_times_slower(EXAMPLES / "mcl" / "correct.ipynb", tmp_path / "mcl_slow.ipynb")
    paths.append(slow)
    names = [p.parent.name if p != slow else "mcl_slow" for p in paths]
    labs = [p.parent.name if p != slow else "mcl" for p in paths]
    assert set(ALONE_TOO) <= set(names)
    alone_at = [i for i, name in enumerate(names) if name in ALONE_TOO]

    alone = grade_all(
        [paths[i] for i in alone_at],
        labs=[labs[i] for i in alone_at],
        names=[names[i] for i in alone_at],
        jobs=2,
        progress=False,
    )
    request.getfixturevalue("busy_loops")
    loaded = grade_all(paths, labs=labs, names=names, jobs=8, progress=False)

    assert {n: g for n, g in _grades(loaded).items() if n in ALONE_TOO} == _grades(alone)
    for r in loaded:
        assert r.total == r.max_points > 0 and not r.limits and not r.errors, r.name
    cpu = {r.name: r.cpu_seconds for r in loaded}
    assert cpu["mcl_slow"] > 2.5 * cpu["mcl"]  # it really is slower, and it kept full marks


def _hanging(path: Path) -> Path:
    """A demo notebook whose `normalize` sleeps 4 s on every call (under the wall limit):
    it takes its whole time budget, 25 s."""
    notebook = json.loads((EXAMPLES / "demo" / "correct.ipynb").read_text())
    for cell in notebook["cells"]:
        if "".join(cell["source"]).startswith("def normalize"):
            cell["source"] = ["import time\n", "def normalize(weights):\n", "    time.sleep(4)\n"]
    path.write_text(json.dumps(notebook))
    return path


def _rows(out: Path) -> dict[str, dict]:
    try:
        return {r["submission"]: r for r in json.loads((out / "gradebook.json").read_text())}
    except (OSError, ValueError):
        return {}


def _descendants(pid: int) -> set[int]:
    """Every process below ``pid`` now (zygotes, pytest runs, workers)."""
    found: set[int] = set()
    todo = [pid]
    while todo:
        parent = todo.pop()
        try:
            with open(f"/proc/{parent}/task/{parent}/children") as f:
                children = [int(c) for c in f.read().split()]
        except OSError:
            continue
        found.update(children)
        todo += children
    return found


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0] not in (b"Z", b"X")
    except OSError:
        return False


DELEGATING = """
import os
import threading
import time


def burn(seconds):
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


def in_main(seconds):
    burn(seconds)
    return seconds


def in_thread(seconds):
    worker = threading.Thread(target=burn, args=(seconds,))
    worker.start()
    worker.join()
    return seconds


def in_child(seconds):
    pid = os.fork()
    if pid == 0:
        burn(seconds)
        os._exit(0)
    os.waitpid(pid, 0)
    return seconds
"""


def test_computing_in_a_thread_or_child_is_charged_as_in_the_main_thread(tmp_path, busy_loops):
    """Beside a busy loop on every core, a call that computes 1 s in its main thread, in a
    thread or in a forked child is charged about 1 s on the wall limits' clock: the time
    its helper waited for a core is the machine's, as the main thread's is."""
    from dataclasses import replace

    from robolab.grading.running.proxy import open_submission
    from tests.grading import TEST_LIMITS, write_notebook

    path = write_notebook(tmp_path / "delegating.ipynb", DELEGATING, lab=None)
    limits = replace(TEST_LIMITS, cpu_seconds=20, wall_seconds=60, total_wall_seconds=300)
    limits = replace(limits, total_cpu_seconds=300)
    with open_submission(path, limits=limits) as sub:
        for name in ("in_main", "in_thread", "in_child"):
            awake, cpu = sub.spent_seconds, sub.spent_cpu_seconds
            assert getattr(sub, name)(1.0) == 1.0
            awake, cpu = sub.spent_seconds - awake, sub.spent_cpu_seconds - cpu
            print(name, awake, cpu, sub.limits_hit())
            assert cpu >= 0.98 and awake <= cpu + 0.5, (name, awake, cpu)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_a_batch_under_load(tmp_path, busy_loops, sig):
    """SIGTERM or SIGINT beside busy loops: the batch stops, the gradebook is valid and
    holds every submission that finished, and no pytest run outlives it."""
    subs = tmp_path / "subs"
    subs.mkdir()
    fast = []
    for name in ("correct", "partial"):
        fast.append(subs / f"a_{name}.ipynb")
        fast[-1].write_bytes((EXAMPLES / "demo" / f"{name}.ipynb").read_bytes())
    hang = _hanging(subs / "zz_hangs.ipynb")
    out = tmp_path / "grades"
    cmd = [sys.executable, "-m", "robolab.cli", "grade", *map(str, [*fast, hang])]
    cmd += ["--out", str(out), "--lab", "demo"]
    with sigint_default():
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # An event, not a sleep: both quick ones are written down (the third takes 25 s).
        deadline = time.monotonic() + HANG
        while len(_rows(out)) < 2:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the batch hangs"
            time.sleep(0.1)
        below = _descendants(proc.pid)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=HANG)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert "Run the same command again" in stderr and "Traceback" not in stderr
    rows = _rows(out)
    assert sorted(rows) == ["a_correct", "a_partial"]
    assert rows["a_correct"]["total"] == 100 and rows["a_partial"]["total"] < 100
    csv_lines = (out / "gradebook.csv").read_text().splitlines()
    assert len(csv_lines) == 3 and csv_lines[0].startswith("submission,")
    # Nothing it started outlives it: zygotes, pytest runs and workers all exit.
    while any(_alive(pid) for pid in below):
        assert time.monotonic() < deadline, "a process outlived the interrupted batch"
        time.sleep(0.1)
