"""Benchmark of robolab.raycast.cast_rays against range_libc's CDDT, on one core.

Run: ``python benchmarks/raycast.py`` (``RANGE_LIBC_PATH=<folder of range_libc's
built Python module>`` adds the CDDT column; without it that column is skipped).
range_libc is not part of robolab: ../shared/perf/RANGE_LIBC.md says how to
build it outside the repository.

Four workloads, 1000 poses in free space x 60 beams each (fixed seeds):

* the office map (``data/office.yaml``, 260 x 420 cells of 0.05 m), range 10 m;
* the bundled maze (203 x 203 cells of 0.05 m), range 4 m;
* a real map: ``../shared/data/olin_ac109_1`` (1088 x 1088 cells of 0.02 m,
  mostly unknown space that rays cross), range 20 m = 1000 cells (skipped when
  the folder is absent);
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
  test.py), ``calc_range_repeat_angles``, clipped to the range.

Ratios are CDDT's time over the compiled kernel's (> 1: ours is faster). The first-call build
(the jump fields of one grid; CDDT's compressed table) is timed the same way.
The compiled kernel's one-time start-up per process (``import numba`` and
loading the kernels from numba's cache) is measured in a child process and
printed separately. Exactness: every range of both backends is checked
against a plain per-ray Python Amanatides-Woo loop on a subset of rays, and
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
from robolab.maps import OccupancyGrid, load_map
from robolab.raycast import RayCaster

N_POSES, N_BEAMS, REPEATS, CHECK_RAYS = timing.sized(1000, 10), 60, 9, timing.sized(2000, 50)
THETA_BINS = 108
REAL_MAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "olin_ac109_1" / "ac109_1.yaml"


def maze_grid() -> OccupancyGrid:
    from robolab import DATA_DIR
    from robolab.maze import write_maze

    path = DATA_DIR / "maze.yaml"
    if not path.is_file():
        path = write_maze(Path(tempfile.mkdtemp()))
    return load_map(path)


def office_grid() -> OccupancyGrid:
    from robolab import DATA_DIR

    return load_map(DATA_DIR / "office.yaml")


def boxes_grid(rng) -> OccupancyGrid:
    occ = np.zeros((2000, 2000), dtype=bool)
    rows, cols = rng.integers(0, 2000, 3000), rng.integers(0, 2000, 3000)
    hs, ws = rng.integers(2, 31, 3000), rng.integers(2, 31, 3000)
    for r, c, h, w in zip(rows, cols, hs, ws, strict=True):  # map construction, not timed
        occ[r : r + h, c : c + w] = True
    return OccupancyGrid(occ.astype(float), 0.05)


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
    """range_libc's module from ``RANGE_LIBC_PATH``, or None (the CDDT column is then skipped)."""
    path = os.environ.get("RANGE_LIBC_PATH")
    if not path:
        return None
    sys.path.insert(0, path)
    try:
        import range_libc
    except ImportError as exc:
        print(f"RANGE_LIBC_PATH={path}: cannot import range_libc ({exc}); CDDT column skipped")
        return None
    return range_libc


class Cddt:
    """range_libc's CDDT on a robolab grid, with its conventions (RANGE_LIBC.md)."""

    def __init__(self, range_libc, grid: OccupancyGrid, max_range: float):
        self.grid, self.max_range = grid, max_range
        self.cells = max_range / grid.resolution
        self.caster = range_libc.PyCDDTCast(
            range_libc.PyOMap(grid.occupied), self.cells, THETA_BINS
        )

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


def main() -> None:
    pinned = timing.pin_to_one_core()
    load0 = timing.load_average()
    rlc = load_range_libc()
    backend = raycast.warm_up()
    if backend != "numba":
        print("numba is not usable here: only the numpy fallback is measured")
    rng = np.random.default_rng(2)
    angles = np.linspace(-np.pi, np.pi, N_BEAMS, endpoint=False)
    cases = [("office 260x420", office_grid(), 10.0), ("maze 203x203", maze_grid(), 4.0)]
    if not REAL_MAP.is_file():  # a missing row would read as a result: fail instead
        raise SystemExit(f"{REAL_MAP} not found: the real-map workload needs ../shared/data")
    cases.append(("olin 1088x1088 2cm", load_map(REAL_MAP), 20.0))
    cases.append(("boxes 2000x2000", boxes_grid(rng), 10.0))
    n_rays = N_POSES * N_BEAMS
    print(
        f"cast_rays, {N_POSES} poses x {N_BEAMS} beams = {n_rays} rays, {pinned}, "
        f"best of {REPEATS} interleaved rounds (process CPU time)"
    )
    print(f"before: {load0}")
    if backend == "numba":
        print(
            f"one-time start-up per process (import numba, load kernels): {startup_seconds():.2f} s"
        )
    head = (
        f"{'map':<19} {'range':>5} | {'cold ms: numba':>14} {'CDDT':>6} {'ratio':>6}"
        f" | {'warm ms: numba':>14} {'CDDT':>6} {'ratio':>6} {'numpy':>6}"
        f" | {'build ms: numba':>15} {'numpy':>7} {'CDDT':>7} | {'CDDT off >1 cell':>16}"
    )
    print(head)
    print("-" * len(head))
    for name, grid, max_range in cases:
        poses = free_poses(grid, N_POSES, rng)
        builds = {"numpy": lambda g=grid: RayCaster(g, backend="numpy")}
        if backend == "numba":
            builds["numba"] = lambda g=grid: RayCaster(g, backend="numba")
        if rlc is not None:
            builds["cddt"] = lambda g=grid, m=max_range: Cddt(rlc, g, m)
        build = timing.interleaved(builds, 3)
        made = {k: f() for k, f in builds.items()}
        casts = {
            k: (lambda c=c, p=poses, m=max_range: c.cast(p, angles, m))
            for k, c in made.items()
            if k != "cddt"
        }
        if rlc is not None:
            made["cddt"].prepare(poses, angles)
            casts["cddt"] = made["cddt"].cast
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
        for k in casts:
            if k == "cddt":
                continue
            err = np.abs(exact * grid.resolution - made[k].cast(poses, angles, max_range)[i, j])
            assert err.max() < 1e-9, f"{k} backend and the exact loop disagree by {err.max()}"
        off = "-"
        if rlc is not None:
            made["cddt"].cast()
            cd = made["cddt"].ranges()[i, j]
            off = f"{np.mean(np.abs(cd - exact * grid.resolution) > grid.resolution):.0%}"

        def ms(key, table):
            return f"{table[key] * 1e3:.1f}" if key in table else "-"

        def ratio(table):  # CDDT's time over ours: > 1, ours is faster
            if not {"cddt", "numba"} <= set(table):
                return "-"
            return f"{table['cddt'] / table['numba']:.2f}x"

        print(
            f"{name:<19} {max_range:>4.0f}m | {ms('numba', cold):>14} {ms('cddt', cold):>6}"
            f" {ratio(cold):>6} | {ms('numba', warm):>14} {ms('cddt', warm):>6} {ratio(warm):>6}"
            f" {ms('numpy', warm):>6} | {ms('numba', build):>15} {ms('numpy', build):>7}"
            f" {ms('cddt', build):>7} | {off:>16}"
        )
    print(f"after: {timing.load_average()}")


if __name__ == "__main__":
    main()
