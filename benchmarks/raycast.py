"""Benchmark of robolab.raycast.cast_rays against range_libc's CDDT and GLT, on one core.

Run: ``python benchmarks/raycast.py`` (``RANGE_LIBC_PATH=<folder of range_libc's
built Python module>`` adds the CDDT and GLT columns; without it they are skipped,
set but not importable it fails; a missing ../shared/data or numba fails too).
range_libc is not part of robolab: ../shared/perf/RANGE_LIBC.md says how to
build it outside the repository.

Five workloads, 1000 poses in free space x 60 beams each (fixed seeds):

* the office map (``data/office.yaml``, 260 x 420 cells of 0.05 m), range 10 m;
* the bundled maze (203 x 203 cells of 0.05 m), range 4 m;
* a real map: ``../shared/data/olin_ac109_1`` (1088 x 1088 cells of 0.02 m,
  mostly unknown space that rays cross), range 20 m = 1000 cells (the benchmark
  fails when the folder is absent);
* :func:`sparse_unknown_grid`: 1056 x 992 cells of 0.02 m, 97 % unknown, sparse
  broken walls (like the held-out Olin map of issue 29), range 20 m;
* a 2000 x 2000 cell map (0.05 m cells) with 3000 random boxes of 2-30 cells a
  side (about 16 % occupied), range 10 m.

Per workload, measured in the same run and interleaved (one call of each
contender per round, best of ``REPEATS`` rounds, process CPU time), twice:
with *cold* caches (64 MiB read and written before every timed call, so no
contender finds its data, or inherits another's, in any cache) and with *warm*
caches (every timed call follows an untimed call of itself, as when one map is
cast on over and over with nothing else in between). A particle filter's step
lies between the two: other work runs between its casts.

* ``cast_rays`` with the compiled kernel (backend ``numba``), the default;
* the same with the numpy fallback (backend ``numpy``);
* range_libc's CDDT (``PyCDDTCast``, 108 angle bins as in range_libc's
  test.py), ``calc_range_repeat_angles``, clipped to the range;
* range_libc's giant lookup table (``PyGiantLUTCast``, same bins) on the two
  small maps (its table is cells x 108 x 2 bytes).

Ratios are CDDT's (GLT's) time over the compiled kernel's (> 1: ours is faster).
The first-call build (the jump fields of one grid; CDDT's compressed table) is
timed the same way.
The compiled kernel's one-time start-up per process (``import numba`` and
loading the kernels from numba's cache) is measured in a child process and
printed separately, and so is a fresh process's first ``cast_rays`` on the
bundled maps with the default ("auto") caster. Per map, iterations per ray
(counted) and cycles per iteration at the clock of /proc/cpuinfo are printed
beside the floor of a random read in an array the fields' size. Exactness:
every range of both backends is checked against a plain per-ray Python
Amanatides-Woo loop on a subset of rays, and
CDDT's error is reported as the share of rays more than one cell off.
The machine's load average is printed before and after (the host is shared).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import timing  # before numpy: one BLAS thread

# isort: split
import numpy as np

from robolab import raycast
from robolab.maps import UNKNOWN, OccupancyGrid, load_map
from robolab.raycast import RayCaster

N_POSES, N_BEAMS, REPEATS, CHECK_RAYS = timing.sized(1000, 10), 60, 9, timing.sized(2000, 50)
THETA_BINS = 108
#: range_libc's giant lookup table (cells x THETA_BINS x 2 bytes) is built on maps up to this size.
GLT_MAX_CELLS = 200_000
REAL_MAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "olin_ac109_1" / "ac109_1.yaml"


def maze_grid() -> OccupancyGrid:
    return load_map(_data("maze.yaml"))


def office_grid() -> OccupancyGrid:
    return load_map(_data("office.yaml"))


def boxes_grid(rng) -> OccupancyGrid:
    occ = np.zeros((2000, 2000), dtype=bool)
    rows, cols = rng.integers(0, 2000, 3000), rng.integers(0, 2000, 3000)
    hs, ws = rng.integers(2, 31, 3000), rng.integers(2, 31, 3000)
    for r, c, h, w in zip(rows, cols, hs, ws, strict=True):  # map construction, not timed
        occ[r : r + h, c : c + w] = True
    return OccupancyGrid(occ.astype(float), 0.05)


def sparse_unknown_grid(rng) -> OccupancyGrid:
    """1056 x 992 cells of 0.02 m, 97 % unknown: a lidar map of one room in a large hall.

    Made to look like the held-out Olin map of issue #29 (same size and resolution,
    97 % unknown): a known free room of 160 x 200 cells whose walls are broken by wide
    gaps (doors, glass, shadows), and short wall fragments scattered over the unknown
    rest (far walls seen through the gaps). Most rays leave through the gaps and run
    until their 20 m range or the map's edge.
    """
    h, w = 1056, 992
    data = np.full((h, w), float(UNKNOWN))
    r0, r1, c0, c1 = 430, 590, 300, 500
    data[r0:r1, c0:c1] = 0.0
    sides = [
        [(r0, c) for c in range(c0, c1)],
        [(r1 - 1, c) for c in range(c0, c1)],
        [(r, c0) for r in range(r0, r1)],
        [(r, c1 - 1) for r in range(r0, r1)],
    ]
    for cells in sides:  # wall pieces of 8-40 cells, gaps of 30-90
        i = 0
        while i < len(cells):
            n_wall = int(rng.integers(8, 41))
            for r, c in cells[i : i + n_wall]:
                data[r, c] = 1.0
            i += n_wall + int(rng.integers(30, 91))
    for _ in range(60):  # fragments of 4-24 cells, horizontal or vertical
        r, c, n_wall = int(rng.integers(0, h)), int(rng.integers(0, w)), int(rng.integers(4, 25))
        if rng.random() < 0.5:
            data[r, c : c + n_wall] = 1.0
        else:
            data[r : r + n_wall, c] = 1.0
    return OccupancyGrid(data, 0.02)


def free_poses(grid: OccupancyGrid, n: int, rng) -> np.ndarray:
    cells = np.argwhere(grid.free)[rng.integers(int(grid.free.sum()), size=n)]
    xy = grid.cell_to_world(cells) + rng.uniform(-0.5, 0.5, (n, 2)) * grid.resolution
    return np.column_stack([xy, rng.uniform(-np.pi, np.pi, n)])


def python_loop(occ: list, u0: float, v0: float, phi: float, limit: float) -> float:
    """One ray, exact Amanatides-Woo in plain Python (cells; ``occ`` nested lists [row][col])."""
    h, w = len(occ), len(occ[0])
    dx, dy = math.cos(phi), math.sin(phi)
    c, r = int(math.floor(u0)), int(math.floor(v0))
    sx, sy = (1 if dx >= 0 else -1), (1 if dy >= 0 else -1)
    tx = ((c + (dx >= 0)) - u0) / dx if dx else math.inf
    ty = ((r + (dy >= 0)) - v0) / dy if dy else math.inf
    tdx, tdy = (abs(1 / dx) if dx else math.inf), (abs(1 / dy) if dy else math.inf)
    t = 0.0
    while t < limit:
        if not (0 <= r < h and 0 <= c < w):
            return limit
        if occ[r][c]:
            return t
        if tx < ty:
            t, c, tx = tx, c + sx, tx + tdx
        else:
            t, r, ty = ty, r + sy, ty + tdy
    return limit


def load_range_libc():
    """range_libc's module from ``RANGE_LIBC_PATH``, or None when the variable is unset.

    Set but not importable is an error: the CDDT and GLT columns would silently vanish.
    """
    path = os.environ.get("RANGE_LIBC_PATH")
    if not path:
        return None
    sys.path.insert(0, path)
    try:
        import range_libc
    except ImportError as exc:
        raise SystemExit(f"RANGE_LIBC_PATH={path}: cannot import range_libc ({exc})") from exc
    return range_libc


class RangeLibc:
    """One of range_libc's casters on a robolab grid, with its conventions (RANGE_LIBC.md).

    ``kind``: ``"PyCDDTCast"`` or ``"PyGiantLUTCast"`` (both with THETA_BINS angle bins).
    """

    def __init__(self, range_libc, kind: str, grid: OccupancyGrid, max_range: float):
        self.grid, self.max_range = grid, max_range
        self.cells = max_range / grid.resolution
        omap = range_libc.PyOMap(grid.occupied)
        self.caster = getattr(range_libc, kind)(omap, self.cells, THETA_BINS)

    def prepare(self, poses, angles):
        uv = self.grid.world_to_map(poses[:, :2])
        heading = poses[:, 2] - self.grid.origin[2]
        rows = np.column_stack([uv[:, 1], uv[:, 0], np.pi / 2 - heading])
        self.ins = np.ascontiguousarray(rows, dtype=np.float32)
        self.angles = np.ascontiguousarray(-angles, dtype=np.float32)
        self.out = np.empty(len(poses) * len(angles), dtype=np.float32)

    def cast(self):
        self.caster.calc_range_repeat_angles(self.ins, self.angles, self.out)

    def ranges(self):
        shape = (self.ins.shape[0], self.angles.shape[0])
        return np.minimum(self.out.reshape(shape), self.cells) * self.grid.resolution


def startup_seconds() -> float:
    """Wall seconds a fresh process needs to import robolab.raycast and load the kernels."""
    code = (
        "import time; t = time.perf_counter(); from robolab import raycast; "
        "b = raycast.warm_up(); print(time.perf_counter() - t, b)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.split()[0])


FIRST_CAST = """
import sys, time
t0 = time.perf_counter()
import numpy as np
from robolab.maps import load_map
from robolab.raycast import cast_rays
grid = load_map(sys.argv[1])
rng = np.random.default_rng(0)
cells = np.argwhere(grid.free)[rng.integers(int(grid.free.sum()), size=int(sys.argv[2]))]
poses = np.column_stack([grid.cell_to_world(cells), rng.uniform(-np.pi, np.pi, len(cells))])
angles = np.linspace(-np.pi, np.pi, 60, endpoint=False)
t1, c1 = time.perf_counter(), time.process_time()
cast_rays(grid, poses, angles, float(sys.argv[3]))
t2, c2 = time.perf_counter(), time.process_time()
print(t1 - t0, t2 - t1, c2 - c1, "numba" in sys.modules)
"""


def first_cast(path: Path, n_poses: int, max_range: float) -> tuple[float, float, float, bool]:
    """A fresh process's import + load, first ``cast_rays`` (wall, CPU) seconds, numba imported?

    The default ("auto") caster, ``ROBOLAB_RAYCAST`` removed from the child's environment.
    """
    env = {k: v for k, v in os.environ.items() if k != "ROBOLAB_RAYCAST"}
    args = [sys.executable, "-c", FIRST_CAST, str(path), str(n_poses), str(max_range)]
    out = subprocess.run(args, capture_output=True, text=True, check=True, env=env).stdout.split()
    return float(out[0]), float(out[1]), float(out[2]), out[3] == "True"


def cpu_hz() -> float:
    """The processor's clock from /proc/cpuinfo (nominal under a hypervisor), or 0 if unknown."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("cpu MHz"):
                return float(line.split(":")[1]) * 1e6
    except OSError:
        pass
    return 0.0


def main() -> None:
    pinned = timing.pin_to_one_core()
    load0 = timing.load_average()
    rlc = load_range_libc()
    # First the fresh processes (numba not loaded in them whatever this one does).
    firsts = {
        (name, n): first_cast(path, n, rng_m)
        for name, path, rng_m in [
            ("office", _data("office.yaml"), 10.0),
            ("maze", _data("maze.yaml"), 4.0),
        ]
        for n in (1, N_POSES)
    }
    backend = raycast.warm_up()
    if backend != "numba":
        raise SystemExit("numba is not usable here: the compiled kernel cannot be measured")
    rng = np.random.default_rng(2)
    angles = np.linspace(-np.pi, np.pi, N_BEAMS, endpoint=False)
    cases = [("office 260x420", office_grid(), 10.0), ("maze 203x203", maze_grid(), 4.0)]
    if not REAL_MAP.is_file():  # a missing row would read as a result: fail instead
        raise SystemExit(f"{REAL_MAP} not found: the real-map workload needs ../shared/data")
    cases.append(("olin 1088x1088 2cm", load_map(REAL_MAP), 20.0))
    cases.append(("unknown 1056x992 2cm", sparse_unknown_grid(rng), 20.0))
    cases.append(("boxes 2000x2000", boxes_grid(rng), 10.0))
    n_rays = N_POSES * N_BEAMS
    hz = cpu_hz()
    print(
        f"cast_rays, {N_POSES} poses x {N_BEAMS} beams = {n_rays} rays, {pinned}, "
        f"best of {REPEATS} interleaved rounds (process CPU time), clock {hz / 1e9:.2f} GHz"
    )
    print(f"before: {load0}")
    print(f"one-time start-up per process (import numba, load kernels): {startup_seconds():.2f} s")
    for (name, n), (setup, cast, cpu, numba_loaded) in firsts.items():
        print(
            f"fresh process, {name}: import + load map {setup:.3f} s, first cast_rays of "
            f"{n} x {N_BEAMS} rays {cast:.3f} s wall, {cpu:.3f} s CPU (numba imported: "
            f"{numba_loaded})"
        )
    head = (
        f"{'map':<20} {'range':>5} | {'cold ms: ours':>13} {'CDDT':>6} {'ratio':>6} {'GLT':>5}"
        f" {'ratio':>6} | {'warm ms: ours':>13} {'CDDT':>6} {'ratio':>6} {'GLT':>5} {'ratio':>6}"
        f" {'numpy':>6} | {'build ms: ours':>14} {'numpy':>6} {'CDDT':>6} | {'CDDT >1 cell':>12}"
    )
    print(head)
    print("-" * len(head))
    costs = []
    for name, grid, max_range in cases:
        poses = free_poses(grid, N_POSES, rng)
        builds = {
            "numba": lambda g=grid: RayCaster(g, backend="numba"),
            "numpy": lambda g=grid: RayCaster(g, backend="numpy"),
        }
        if rlc is not None:
            builds["cddt"] = lambda g=grid, m=max_range: RangeLibc(rlc, "PyCDDTCast", g, m)
        build = timing.interleaved(builds, 3)
        made = {k: f() for k, f in builds.items()}
        if rlc is not None and grid.data.size <= GLT_MAX_CELLS:  # its table: cells x bins x 2 B
            made["glt"] = RangeLibc(rlc, "PyGiantLUTCast", grid, max_range)
        casts = {
            k: (lambda c=c, p=poses, m=max_range: c.cast(p, angles, m))
            for k, c in made.items()
            if k in ("numba", "numpy")
        }
        for k in ("cddt", "glt"):
            if k in made:
                made[k].prepare(poses, angles)
                casts[k] = made[k].cast
        cold = timing.interleaved(
            {k: f for k, f in casts.items() if k != "numpy"}, REPEATS, timing.flush_caches
        )
        warm = timing.interleaved(casts, REPEATS, lambda fn: fn())

        # exactness: both backends against the per-ray Python loop on a subset of rays
        occ = grid.occupied.tolist()
        uv = grid.world_to_map(poses[:, :2])
        i, j = np.divmod(rng.choice(n_rays, CHECK_RAYS, replace=False), N_BEAMS)
        limit = max_range / grid.resolution
        phi = poses[i, 2] - grid.origin[2] + angles[j]
        exact = np.array(
            [python_loop(occ, uv[k, 0], uv[k, 1], f, limit) for k, f in zip(i, phi, strict=True)]
        )
        for k in ("numba", "numpy"):
            err = np.abs(exact * grid.resolution - made[k].cast(poses, angles, max_range)[i, j])
            assert err.max() < 1e-9, f"{k} backend and the exact loop disagree by {err.max()}"
        off = "-"
        if rlc is not None:
            made["cddt"].cast()
            cd = made["cddt"].ranges()[i, j]
            off = f"{np.mean(np.abs(cd - exact * grid.resolution) > grid.resolution):.0%}"

        def ms(key, table):
            return f"{table[key] * 1e3:.1f}" if key in table else "-"

        def ratio(table, other):  # the other's time over ours: > 1, ours is faster
            if other not in table:
                return "-"
            return f"{table[other] / table['numba']:.2f}x"

        print(
            f"{name:<20} {max_range:>4.0f}m | {ms('numba', cold):>13} {ms('cddt', cold):>6}"
            f" {ratio(cold, 'cddt'):>6} {ms('glt', cold):>5} {ratio(cold, 'glt'):>6}"
            f" | {ms('numba', warm):>13} {ms('cddt', warm):>6} {ratio(warm, 'cddt'):>6}"
            f" {ms('glt', warm):>5} {ratio(warm, 'glt'):>6} {ms('numpy', warm):>6}"
            f" | {ms('numba', build):>14} {ms('numpy', build):>6} {ms('cddt', build):>6}"
            f" | {off:>12}"
        )
        costs.append((name, grid, poses, max_range, warm["numba"], cold["numba"]))
    print(f"after: {timing.load_average()}")
    print_step_costs(costs, angles, hz)


def print_step_costs(costs, angles, hz) -> None:
    """Cycles per iteration (jump or cell step) of the compiled kernel, beside its memory floor.

    Iterations per ray are counted by re-running the kernel's own step function
    ray by ray. The floor: one random read per iteration from an array the size of
    the jump fields, either one dependent chain (the latency of a look-up) or
    ``LANES`` chains interleaved as the kernel's lanes are (look-ups overlapping).
    """
    from numba import njit

    from robolab import _raycast_jit as jit

    @njit(cache=False)
    def count_steps(fields, uv, heading, angles, limit, h, w):
        n, b = uv.shape[0], angles.shape[0]
        ca, sa, ch, sh = np.cos(angles), np.sin(angles), np.cos(heading), np.sin(heading)
        flat, plane, wp = fields.ravel(), fields.shape[1] * fields.shape[2], fields.shape[2]
        geometry = (n, b, uv, ch, sh, ca, sa, limit, h, w, plane, wp, flat, fields.shape[0] == 8)
        steps = 0
        for i in range(n):
            for j in range(b):
                state, enters = jit._start_off_map(i, j, geometry)
                done = not enters
                while not done:
                    state, done, _, _ = jit._step(flat, wp, state)
                    steps += 1
        return steps

    @njit(cache=False)
    def chase(nxt, steps, lanes):
        p = np.arange(lanes) * (nxt.shape[0] // lanes)
        for _ in range(steps // lanes):
            for k in range(lanes):
                p[k] = nxt[p[k]]
        return p.sum()

    def floor_ns(n_bytes, lanes, rng):
        n = max(n_bytes // 4, 1024)
        order = rng.permutation(n).astype(np.int32)
        nxt = np.empty(n, np.int32)
        nxt[order] = np.roll(order, -1)  # one random cycle through the whole array
        steps = 600_000
        chase(nxt, 1000, lanes)
        t = timing.best_of(chase, 3, nxt, steps, lanes).cpu
        return t / steps * 1e9

    rng = np.random.default_rng(4)
    print(
        f"compiled kernel, per iteration (a jump or an exact cell step) at {hz / 1e9:.2f} GHz;"
        f" floor: a random read in an array the size of the fields, one chain (latency) or"
        f" {jit.LANES} interleaved (the kernel's lanes)"
    )
    head = (
        f"{'map':<20} | {'fields MB':>9} {'iter/ray':>8} | {'warm ns/iter':>12} {'cycles':>6}"
        f" | {'cold ns/iter':>12} {'cycles':>6} | {'floor ns: 1 chain':>17} {'cycles':>6}"
        f" | {f'{jit.LANES} chains':>9} {'cycles':>6}"
    )
    print(head)
    print("-" * len(head))
    for name, grid, poses, max_range, warm, cold in costs:
        caster = RayCaster(grid, backend="numba")
        fields = caster._fields_for("numba")
        uv = grid.world_to_map(poses[:, :2])
        heading = poses[:, 2] - grid.origin[2]
        h, w = grid.shape
        steps = count_steps(fields, uv, heading, angles, max_range / grid.resolution, h, w)
        per_ray = steps / (len(poses) * len(angles))
        ns_warm, ns_cold = warm / steps * 1e9, cold / steps * 1e9
        one, lanes = floor_ns(fields.nbytes, 1, rng), floor_ns(fields.nbytes, jit.LANES, rng)
        print(
            f"{name:<20} | {fields.nbytes / 1e6:>9.2f} {per_ray:>8.2f} | {ns_warm:>12.1f}"
            f" {ns_warm * hz / 1e9:>6.0f} | {ns_cold:>12.1f} {ns_cold * hz / 1e9:>6.0f}"
            f" | {one:>17.1f} {one * hz / 1e9:>6.0f} | {lanes:>9.1f} {lanes * hz / 1e9:>6.0f}"
        )


def _data(name: str) -> Path:
    """A bundled map's yaml (the maze is written to a scratch folder if it is missing)."""
    from robolab import DATA_DIR
    from robolab.maze import write_maze

    path = DATA_DIR / name
    if name == "maze.yaml" and not path.is_file():
        path = write_maze(Path(tempfile.mkdtemp()))
    if not path.is_file():
        raise SystemExit(f"{path} not found: the bundled maps are part of the package")
    return path


if __name__ == "__main__":
    main()
