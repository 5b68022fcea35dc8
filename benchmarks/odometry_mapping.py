"""Benchmark: scans integrated per second by the lab 04 counting map (and the log-odds map).

Integrates the 360-beam scans of ``data/mapping.bag`` (ground-truth poses) into
a 0.05 m grid of the office (260 x 420 cells) with
``solutions.odometry_mapping.counting_map_update``, pinned to one core, against
a baseline measured in the same run: the same update written as a per-beam
Python loop (an integer Amanatides-Woo walk per beam, the way the seed's
MATLAB / Python code traces beams), timed on a subset of scans and scaled.
``logodds_update`` (Table 9.2 over every cell in range) is timed too.

Per-scan cost vs map size: both updates on the office grid and on a grid of
16x the cells (the office in one corner, about 1.75 M cells), interleaved, best
of 3 by process CPU time; next to them the counting update as it was before
(``np.bincount`` with ``minlength`` = the whole map, plus per-cell checks),
measured in the same run. The updates' remaining full-map work is the copy
their contract requires (new arrays, inputs unchanged).

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
from robolab.maps import OccupancyGrid, load_map
from solutions.odometry_mapping import (
    INVERSE_SENSOR_MODEL,
    _beam_ends,
    _scan_arrays,
    beam_cells,
    counting_map_update,
    logodds_update,
)

N_SCANS = timing.sized(200, 5)  # vectorized: every 4th scan of the bag
BASELINE_SCANS = timing.sized(10, 2)


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


def full_map_counting_update(hits, visits, scan, pose, grid):
    """The counting update as it was: per-cell checks and whole-map bincounts per scan."""
    hits, visits = np.asarray(hits, float).copy(), np.asarray(visits, float).copy()
    if not (np.all(np.isfinite(hits)) and np.all(np.isfinite(visits))):
        raise ValueError("hits and visits must be finite")
    if np.any(hits < 0) or np.any(visits < 0):
        raise ValueError("hits and visits must be non-negative counts")
    ends, is_hit = _beam_ends(*_scan_arrays(scan), np.asarray(pose, float))
    start = grid.world_to_map(np.asarray(pose, float)[:2])[::-1]
    cells, _ = beam_cells(start, grid.world_to_map(ends)[:, ::-1])
    inside = grid.contains_cell(cells)
    flat = np.ravel_multi_index((cells[inside, 0], cells[inside, 1]), grid.shape)
    visits += np.bincount(flat, minlength=visits.size).reshape(grid.shape)
    end_cells = grid.world_to_cell(ends[is_hit])
    ok = grid.contains_cell(end_cells)
    flat = np.ravel_multi_index((end_cells[ok, 0], end_cells[ok, 1]), grid.shape)
    hits += np.bincount(flat, minlength=hits.size).reshape(grid.shape)
    return hits, visits


def map_size_table(scans, poses, grid):
    """CPU ms per scan of each update on ``grid`` and on a 16x larger grid; printed."""
    big = OccupancyGrid(
        np.full((grid.shape[0] * 4, grid.shape[1] * 4), -1.0), grid.resolution, grid.origin
    )
    subset = slice(0, 40)

    def logodds(hits, visits, scan, pose, g):
        return logodds_update(hits, scan, pose, g, INVERSE_SENSOR_MODEL), visits

    updates = {
        "counting": counting_map_update,
        "counting before (full-map bincount)": full_map_counting_update,
        "log-odds": logodds,
    }
    calls = {
        (name, label): (lambda u=u, g=g: run(u, scans[subset], poses[subset], g))
        for name, u in updates.items()
        for label, g in (("office", grid), ("16x cells", big))
    }
    a = calls["counting", "16x cells"]()
    b = calls["counting before (full-map bincount)", "16x cells"]()
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    best = timing.interleaved(calls, 3)
    n = len(scans[subset])
    print(
        f"per-scan cost vs map size (CPU ms per scan, {n} scans; office {grid.data.size} cells, "
        f"16x: {big.data.size} cells)"
    )
    print(f"{'update':<40}{'office':>10}{'16x cells':>11}{'16x / office':>14}")
    for name in updates:
        small, large = best[name, "office"] / n, best[name, "16x cells"] / n
        print(f"{name:<40}{small * 1e3:>10.2f}{large * 1e3:>11.2f}{large / small:>13.1f}x")


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
    t_vec = timing.best_of(run, 3, counting_map_update, scans, poses, grid).cpu
    sub = slice(0, n, n // BASELINE_SCANS)
    t_loop_sub = timing.best_of(
        run, 1, counting_update_python_loop, scans[sub], poses[sub], grid
    ).cpu
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

    t_log = timing.best_of(logodds_run, 2, scans[:50], poses[:50]).cpu / 50 * n

    print(
        f"lab 04 mapping: {n} scans of {s.beams} beams from data/mapping.bag, "
        f"grid {grid.shape[0]} x {grid.shape[1]} cells of {grid.resolution} m ({pinned}; "
        f"{timing.load_average()})"
    )
    print("process CPU time (the machine is shared; wall time counts other processes' turns)")
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
    print()
    map_size_table(scans, poses, grid)


if __name__ == "__main__":
    main()
