"""Peak memory of a Gradescope-style run, per lab, in a container-sized box.

Gradescope runs ``run_autograder`` once per submission in a container; measured from
outside, grading the MCL, beam-model and Bayes labs peaked at 323 MB and scored 100 with
384 MB and half a CPU. This benchmark keeps that true. For each lab it builds the
autograder bundle (``robolab.grading.exports.gradescope.build_bundle``), lays it out as
``/autograder`` (``source/``, ``submission/``, ``results/``), runs its ``setup.sh`` (a
fresh venv, the answers made root-only), and runs the bundle's own ``run_autograder`` on the lab's
correct example submission, after the bundle's ``setup.sh`` built its venv:

- inside a cgroup limited like the container (``--memory`` MB, ``--cpus`` CPUs; cgroup
  v1 or v2, when this process may create one: as root), whose peak
  (``memory.max_usage_in_bytes`` / ``memory.peak``) is what the container's limit
  sees, page cache included;
- while sampling every 20 ms the resident set of the whole process tree (the sum of
  VmRSS over the runner, its zygotes and workers: an upper bound, since pages shared
  after fork count once per process).

It prints one row per lab: score, wall and CPU seconds, both peaks. ``--check`` exits 1
when a lab does not score full marks or its peak reaches the memory limit.

    python benchmarks/gradescope_memory.py [--labs mcl beam_model bayes] [--memory 384]
        [--cpus 0.5] [--check]

Under ``ROBOLAB_BENCH_TINY=1`` the default is the Bayes lab alone. Its ``setup.sh``
still pip-installs the bundle's dependencies into a fresh venv: it needs the network
(tests/test_benchmarks.py skips it for that reason).
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
import threading
import time
import zipfile
from pathlib import Path

from robolab.grading.exports.gradescope import BundleOptions, build_bundle

REPO = Path(__file__).resolve().parents[1]
TINY = os.environ.get("ROBOLAB_BENCH_TINY") == "1"


def _tree_rss(root_pid: int) -> int:
    """Sum of VmRSS (bytes) of ``root_pid`` and all its descendants."""
    parent: dict[int, int] = {}
    rss: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/status") as f:
                fields = dict(line.split(":", 1) for line in f if ":" in line)
        except OSError:
            continue
        pid = int(entry)
        parent[pid] = int(fields.get("PPid", "0"))
        rss[pid] = int(fields.get("VmRSS", "0 kB").split()[0]) * 1024
    total, todo = 0, [root_pid]
    children: dict[int, list[int]] = {}
    for pid, ppid in parent.items():
        children.setdefault(ppid, []).append(pid)
    while todo:
        pid = todo.pop()
        total += rss.get(pid, 0)
        todo += children.get(pid, [])
    return total


class Box:
    """A cgroup with a memory limit and a CPU quota (None when none can be made here)."""

    def __init__(self, name: str, memory_mb: int, cpus: float):
        self.paths: list[Path] = []
        self.peak_file: Path | None = None
        v2 = Path("/sys/fs/cgroup/cgroup.controllers")
        try:
            if v2.exists():
                path = Path("/sys/fs/cgroup") / name
                path.mkdir()
                self.paths = [path]
                (path / "memory.max").write_text(str(memory_mb << 20))
                (path / "memory.swap.max").write_text("0")
                (path / "cpu.max").write_text(f"{int(cpus * 100000)} 100000")
                self.peak_file = path / "memory.peak"
            else:
                mem = Path("/sys/fs/cgroup/memory") / name
                cpu = Path("/sys/fs/cgroup/cpu") / name
                mem.mkdir()
                self.paths.append(mem)
                cpu.mkdir()
                self.paths.append(cpu)
                (mem / "memory.limit_in_bytes").write_text(str(memory_mb << 20))
                (cpu / "cpu.cfs_period_us").write_text("100000")
                (cpu / "cpu.cfs_quota_us").write_text(str(int(cpus * 100000)))
                self.peak_file = mem / "memory.max_usage_in_bytes"
        except OSError as exc:
            print(f"(no cgroup: {exc.strerror or exc}; sampling /proc only)", file=sys.stderr)
            self.close()
            self.paths, self.peak_file = [], None

    def enter(self) -> None:
        """Move the calling process into the box (a ``preexec_fn``)."""
        for path in self.paths:
            (path / "cgroup.procs").write_text(str(os.getpid()))

    def peak(self) -> int | None:
        try:
            return int(self.peak_file.read_text()) if self.peak_file else None
        except (OSError, ValueError):
            return None

    def close(self) -> None:
        for path in self.paths:
            try:
                path.rmdir()
            except OSError:
                pass


def _clean_env(**extra) -> dict:
    """This environment without this venv: setup.sh builds the bundle's own."""
    env = {
        k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME")
    }
    env["PATH"] = os.pathsep.join(
        p for p in env.get("PATH", "").split(os.pathsep) if not p.startswith(sys.prefix)
    )
    return env | extra


def _autograder(lab: str, home: Path) -> Path:
    """``home`` as /autograder for ``lab`` after Gradescope's setup.sh ran in it, with the
    lab's correct example submitted. The venv is made by the first lab's setup.sh (minutes)
    and reused by the next ones', which then only reinstall robolab from the new bundle."""
    for old in ("source", "submission", "results"):
        shutil.rmtree(home / old, ignore_errors=True)
    bundle = home.parent / "autograder.zip"
    build_bundle(lab, bundle, options=BundleOptions())
    with zipfile.ZipFile(bundle) as zf:
        zf.extractall(home / "source")
    for script in ("setup.sh", "run_autograder"):
        (home / "source" / script).chmod(0o755)
    shutil.copy(home / "source" / "run_autograder", home / "run_autograder")
    env = _clean_env(ROBOLAB_AUTOGRADER_DIR=str(home), ROBOLAB_SETUP_PYTHON=sys._base_executable)
    done = subprocess.run(
        ["bash", str(home / "source" / "setup.sh")],
        env=env,
        cwd=home,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    if done.returncode != 0:
        raise SystemExit(f"setup.sh failed for {lab}:\n{done.stdout[-2000:]}{done.stderr[-2000:]}")
    (home / "submission").mkdir()
    shutil.copy(REPO / "examples" / "submissions" / lab / "correct.ipynb", home / "submission")
    (home / "submission_metadata.json").write_text(json.dumps({"users": []}))
    return home


def measure(lab: str, memory_mb: int, cpus: float, home: Path) -> dict:
    _autograder(lab, home)
    env = _clean_env(ROBOLAB_AUTOGRADER_DIR=str(home))
    box = Box(f"robolab-gs-{os.getpid()}-{lab}", memory_mb, cpus)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    proc = subprocess.Popen(
        ["bash", str(home / "run_autograder")],
        env=env,
        cwd=home,
        preexec_fn=box.enter,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    peak_rss = 0
    done = threading.Event()

    def sample():
        nonlocal peak_rss
        while not done.is_set():
            peak_rss = max(peak_rss, _tree_rss(proc.pid))
            time.sleep(0.02)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    output, _ = proc.communicate()
    done.set()
    sampler.join()
    wall = time.monotonic() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cgroup_peak = box.peak()
    box.close()
    try:
        results = json.loads((home / "results" / "results.json").read_text())
    except (OSError, ValueError):
        results = {"score": None, "tests": []}
    possible = sum(t.get("max_score", 0) for t in results.get("tests", []))
    lost = [
        f"{t.get('name')}: {str(t.get('output', ''))[:300]}"
        for t in results.get("tests", [])
        if t.get("score", 0) < t.get("max_score", 0)
    ]
    return {
        "lab": lab,
        "exit": proc.returncode,
        "score": results.get("score"),
        "possible": possible,
        "wall": wall,
        "cpu": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
        "tree_rss_mb": peak_rss / 2**20,
        "cgroup_peak_mb": None if cgroup_peak is None else cgroup_peak / 2**20,
        "output": output + "".join(f"\nlost: {line}" for line in lost),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--labs", nargs="+", default=["bayes"] if TINY else ["mcl", "beam_model", "bayes"]
    )
    p.add_argument("--memory", type=int, default=384, help="container memory limit, MB")
    p.add_argument("--cpus", type=float, default=0.5, help="container CPU quota")
    p.add_argument("--check", action="store_true", help="exit 1 unless every lab fits and scores")
    args = p.parse_args()
    print(f"load before: {os.getloadavg()[0]:.2f}; box: {args.memory} MB, {args.cpus} CPU")
    print(
        f"{'lab':<12} {'score':>9} {'wall s':>7} {'CPU s':>6} {'tree RSS MB':>12} "
        f"{'cgroup peak MB':>15}"
    )
    failed = False
    tmp = tempfile.mkdtemp(prefix="gs-bench-", dir="/tmp")
    os.chmod(tmp, 0o755)  # the worker's uid reaches the venv, as in the container
    home = Path(tmp) / "autograder"
    home.mkdir()
    try:
        rows = [measure(lab, args.memory, args.cpus, home) for lab in args.labs]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    for r in rows:
        lab = r["lab"]
        peak = r["cgroup_peak_mb"]
        print(
            f"{lab:<12} {r['score']!s:>5}/{r['possible']:<3g} {r['wall']:7.1f} {r['cpu']:6.1f} "
            f"{r['tree_rss_mb']:12.0f} {'-' if peak is None else f'{peak:15.0f}':>15}"
        )
        fits = (peak if peak is not None else r["tree_rss_mb"]) < args.memory
        if r["exit"] != 0 or r["score"] != r["possible"] or not fits:
            failed = True
            print(r["output"][-2000:], file=sys.stderr)
    print(f"load after: {os.getloadavg()[0]:.2f}")
    return 1 if (failed and args.check) else 0


if __name__ == "__main__":
    sys.exit(main())
