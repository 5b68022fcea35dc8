"""Benchmark of robolab.raycast.cast_rays: rays per second on one core.

Run: ``python benchmarks/raycast.py``. Two maps, 1000 poses in free space x 60
beams each (fixed seeds):

* the bundled maze (203 x 203 cells of 0.05 m, laser range 4 m);
* a 2000 x 2000 cell map (0.05 m cells, 100 m square) with 3000 random
  axis-aligned boxes of 2-30 cells a side (about 16 % occupied), range 10 m.

The baseline is a plain per-ray Python loop (the same exact Amanatides-Woo
traversal, one ray at a time), timed on a subset of the rays and scaled; its
ranges are checked against cast_rays on that subset. Speeds are best of 5 runs,
both by wall clock and by process CPU time (the CPU figure is the steadier one
on a shared machine). The issue's target is 2 million rays per second.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import timing  # before numpy: one BLAS thread

# isort: split
import numpy as np

from robolab.maps import OccupancyGrid, load_map
from robolab.raycast import cast_rays

N_POSES, N_BEAMS, REPEATS, BASELINE_RAYS = 1000, 60, 5, 3000
TARGET = 2e6


def maze_grid() -> OccupancyGrid:
    from robolab import DATA_DIR
    from robolab.maze import write_maze

    path = DATA_DIR / "maze.yaml"
    if not path.is_file():
        path = write_maze(Path(tempfile.mkdtemp()))
    return load_map(path)


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


def main() -> None:
    pinned = timing.pin_to_one_core()
    rng = np.random.default_rng(2)
    angles = np.linspace(-np.pi, np.pi, N_BEAMS, endpoint=False)
    cases = [("maze 203x203", maze_grid(), 4.0), ("boxes 2000x2000", boxes_grid(rng), 10.0)]
    n_rays = N_POSES * N_BEAMS
    print(f"cast_rays, {N_POSES} poses x {N_BEAMS} beams = {n_rays} rays, {pinned}")
    header = (
        f"{'map':<16} {'range':>6} {'first call':>11} {'M rays/s wall':>14} {'M rays/s cpu':>13}"
        f" {'loop M rays/s':>14} {'speed-up':>9} {'target 2M':>10}"
    )
    print(header)
    print("-" * len(header))
    for name, grid, max_range in cases:
        poses = free_poses(grid, N_POSES, rng)
        t0 = time.perf_counter()
        ranges = cast_rays(grid, poses, angles, max_range)  # builds and caches the distance field
        first = time.perf_counter() - t0
        best = timing.best_of(cast_rays, REPEATS, grid, poses, angles, max_range)
        wall, cpu = best.wall, best.cpu

        # Baseline on a subset of rays, checked against cast_rays.
        occ = grid.occupied.tolist()
        uv = grid.world_to_map(poses[:, :2])
        pick = rng.choice(n_rays, BASELINE_RAYS, replace=False)
        i, j = np.divmod(pick, N_BEAMS)
        phi = poses[i, 2] + angles[j]
        limit = max_range / grid.resolution
        c0 = time.process_time()
        base = [python_loop(occ, uv[k, 0], uv[k, 1], f, limit) for k, f in zip(i, phi, strict=True)]
        base_cpu = (time.process_time() - c0) / BASELINE_RAYS * n_rays
        err = np.abs(np.asarray(base) * grid.resolution - ranges[i, j]).max()
        assert err < 1e-9, f"baseline and cast_rays disagree by {err}"

        speed, base_speed = n_rays / cpu, n_rays / base_cpu
        print(
            f"{name:<16} {max_range:>5.0f}m {first * 1e3:>9.0f}ms {n_rays / wall / 1e6:>14.2f}"
            f" {speed / 1e6:>13.2f} {base_speed / 1e6:>14.3f} {speed / base_speed:>8.0f}x"
            f" {'yes' if speed >= TARGET else 'NO':>10}"
        )
        print(f"{'':<16} mean range {ranges.mean():.2f} m, {np.mean(ranges < max_range):.0%} hits")


if __name__ == "__main__":
    main()
