"""Benchmark: scans integrated per second by the lab 04 counting map (and the log-odds map).

Integrates the 360-beam scans of ``data/mapping.bag`` (ground-truth poses) into
a 0.05 m grid of the office (260 x 420 cells) with
``solutions.odometry_mapping.counting_map_update``, pinned to one core, against
a baseline measured in the same run: the same update written as a per-beam
Python loop (an integer Amanatides-Woo walk per beam, the way the seed's
MATLAB / Python code traces beams), timed on a subset of scans and scaled.
``logodds_update`` (Table 9.2 over every cell in range) is timed too.

Target (issue 8): >= 200 scans/s on one core for the counting map (a 60 s bag
at 10 Hz maps in about 3 s).

Run: ``python benchmarks/odometry_mapping.py``
"""

from __future__ import annotations

import math

import timing  # before numpy: one BLAS thread

# isort: split
import numpy as np

from robolab import DATA_DIR
from robolab.bag import BagReader, laser_pose_in_base
from robolab.geometry import compose
from robolab.maps import load_map
from solutions.odometry_mapping import INVERSE_SENSOR_MODEL, counting_map_update, logodds_update

N_SCANS = 200  # vectorized: every 4th scan of the bag
BASELINE_SCANS = 10


def counting_update_python_loop(hits, visits, scan, pose, grid):
    """The baseline: one beam at a time, one cell at a time (integer grid walk)."""
    hits, visits = hits.copy(), visits.copy()
    rows, cols = grid.shape
    rmin, rmax = scan["range_min"], scan["range_max"]
    (sx, sy) = grid.world_to_map(pose[:2])
    for r, a in zip(scan["ranges"].tolist(), scan["angles"].tolist(), strict=True):
        if math.isnan(r) or r <= 0 or r < rmin:
            continue
        hit = r < rmax
        d = r if hit else rmax
        ex = sx + d * math.cos(pose[2] + a) / grid.resolution
        ey = sy + d * math.sin(pose[2] + a) / grid.resolution
        cx, cy = math.floor(sx), math.floor(sy)
        end_x, end_y = math.floor(ex), math.floor(ey)
        dx, dy = ex - sx, ey - sy
        step_x, step_y = (1 if dx > 0 else -1), (1 if dy > 0 else -1)
        t_dx = abs(1.0 / dx) if dx else math.inf
        t_dy = abs(1.0 / dy) if dy else math.inf
        t_x = ((cx + (step_x > 0)) - sx) / dx if dx else math.inf
        t_y = ((cy + (step_y > 0)) - sy) / dy if dy else math.inf
        while True:
            if 0 <= cy < rows and 0 <= cx < cols:
                visits[cy, cx] += 1
            if cx == end_x and cy == end_y:
                break
            if t_x < t_y:
                cx, t_x = cx + step_x, t_x + t_dx
            else:
                cy, t_y = cy + step_y, t_y + t_dy
            if abs(cx - end_x) > 1e6:  # safety net for degenerate beams
                break
        if hit and 0 <= end_y < rows and 0 <= end_x < cols:
            hits[end_y, end_x] += 1
    return hits, visits


def run(update, scans, poses, grid, **kw):
    hits, visits = np.zeros(grid.shape), np.zeros(grid.shape)
    for scan, pose in zip(scans, poses, strict=True):
        hits, visits = update(hits, visits, scan, pose, grid, **kw)
    return hits, visits


def main():
    pinned = timing.pin_to_one_core()
    with BagReader(DATA_DIR / "mapping.bag") as bag:
        s = bag.scans("/base_scan")
        truth = bag.odometry("/ground_truth")
        mount = laser_pose_in_base(bag.tf(), s.frame_id)
    idx = np.arange(0, len(s), max(len(s) // N_SCANS, 1))[:N_SCANS]
    scans = [
        {
            "ranges": s.ranges[i].astype(float),
            "angles": s.angles,
            "range_min": s.range_min,
            "range_max": s.range_max,
        }
        for i in idx
    ]
    poses = compose(truth.at(s.stamps[idx]), mount)
    true_map = load_map(DATA_DIR / "office.yaml")
    grid = true_map.with_data(np.full(true_map.shape, -1.0))
    n = len(scans)

    run(counting_map_update, scans[:5], poses[:5], grid)  # warm-up
    t_vec = timing.best_of(run, 3, counting_map_update, scans, poses, grid).wall
    sub = slice(0, n, n // BASELINE_SCANS)
    t_loop_sub = timing.best_of(
        run, 1, counting_update_python_loop, scans[sub], poses[sub], grid
    ).wall
    t_loop = t_loop_sub / len(scans[sub]) * n
    # the two implementations agree on the subset
    a = run(counting_map_update, scans[sub], poses[sub], grid)
    b = run(counting_update_python_loop, scans[sub], poses[sub], grid)
    agree = all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))

    def logodds_run(scans_, poses_):
        l = np.zeros(grid.shape)  # noqa: E741
        for scan, pose in zip(scans_, poses_, strict=True):
            l = logodds_update(l, scan, pose, grid, INVERSE_SENSOR_MODEL)  # noqa: E741
        return l

    t_log = timing.best_of(logodds_run, 2, scans[:50], poses[:50]).wall / 50 * n

    print(
        f"lab 04 mapping: {n} scans of {s.beams} beams from data/mapping.bag, "
        f"grid {grid.shape[0]} x {grid.shape[1]} cells of {grid.resolution} m ({pinned})"
    )
    print(f"{'implementation':<56}{'ms / scan':>11}{'scans / s':>11}{'speed-up':>10}")
    print(
        f"{'counting, per-beam Python loop (' + f'{len(scans[sub])} scans timed, scaled)':<56}"
        f"{t_loop / n * 1e3:>11.2f}{n / t_loop:>11.0f}{1.0:>10.1f}"
    )
    print(
        f"{'counting, vectorized (solutions.odometry_mapping)':<56}"
        f"{t_vec / n * 1e3:>11.2f}{n / t_vec:>11.0f}{t_loop / t_vec:>10.1f}"
    )
    print(
        f"{'log-odds, Table 9.2 over all cells in range':<56}"
        f"{t_log / n * 1e3:>11.2f}{n / t_log:>11.0f}{'':>10}"
    )
    print(f"baseline and vectorized counts identical on the timed subset: {agree}")
    print(f"target >= 200 scans/s (counting): {'met' if n / t_vec >= 200 else 'NOT met'}")


if __name__ == "__main__":
    main()
