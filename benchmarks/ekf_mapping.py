"""Benchmark for lab 06: the hot parts of one EKF-with-mapping step against the seed's loops.

Baselines, measured in the same run: the seed's ``mapping`` (a Python loop over
every cell calling a per-cell inverse sensor model) and its
``measurementFunction`` (a 0.1-step while loop per beam), both transcribed
to Python. Run pinned to one core::

    .venv/bin/python benchmarks/ekf_mapping.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import timing  # before numpy: one BLAS thread

# isort: split
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robolab.geometry import wrap_angle  # noqa: E402
from robolab.maps import OccupancyGrid  # noqa: E402
from robolab.raycast import cast_rays  # noqa: E402
from solutions import ekf_mapping as lab  # noqa: E402


def seed_inverse_sense_model(row, col, state, zmax, scan):
    """Seed 000's provided model for one cell (Table 9.2), as the seed calls it per cell."""
    b = len(scan)
    angles = 2 * np.pi * np.arange(b) / b
    cx, cy = col + 0.5, row + 0.5
    r = np.hypot(cx - state[0], cy - state[1])
    phi = np.arctan2(cy - state[1], cx - state[0]) - state[2]
    diffs = np.abs(wrap_angle(phi - angles))
    k = int(np.argmin(diffs))
    if r > min(zmax, scan[k] + 0.5) or diffs[k] > np.pi / b:
        return 0.0
    if scan[k] < zmax and abs(r - scan[k]) < 0.5:
        return 1.0
    return -0.2 if r <= scan[k] else 0.0


def seed_mapping(state, m, scan, zmax=20.0):
    m = m.copy()
    for row in range(m.shape[0]):
        for col in range(m.shape[1]):
            m[row, col] += seed_inverse_sense_model(row, col, state, zmax, scan)
    return m


def seed_measurement_function(state, m, n_beams=36, max_range=20.0):
    """Seed 000's measurementFunction (0.1 steps, round to a cell; 0-based cells here)."""
    x, y, theta = state
    z = np.zeros(n_beams)
    for i in range(n_beams):
        a = theta + 2 * np.pi * i / n_beams
        r = 0.0
        while r < max_range:
            c, rr = int(np.floor(x + r * np.cos(a))), int(np.floor(y + r * np.sin(a)))
            if not (0 <= rr < m.shape[0] and 0 <= c < m.shape[1]):
                r = max_range
                break
            if m[rr, c] > 0.5:
                break
            r += 0.1
        z[i] = min(r, max_range)
    return z


def _calls(fn, number):
    for _ in range(number):
        fn()


def best(fn, number):
    """Seconds per call: the best of 5 runs of ``number`` calls, by wall clock."""
    return timing.best_of(_calls, 5, fn, number).wall / number


def main():
    timing.pin_to_one_core()
    world = np.zeros((40, 40))
    world[[0, -1], :] = 1
    world[:, [0, -1]] = 1
    world[16:24, 16:24] = 1
    grid = OccupancyGrid(world, 1.0)
    state = np.array([10.3, 10.2, 0.3])
    scan = cast_rays(grid, state, np.deg2rad(10.0 * np.arange(36)), 20.0)[0]
    evidence = np.where(world > 0, 3.0, -1.0)
    np.testing.assert_allclose(
        lab.update_map(evidence, state, scan), seed_mapping(state, evidence, scan)
    )

    rows = []
    t_seed = best(lambda: seed_mapping(state, evidence, scan), 1)
    t_ours = best(lambda: lab.update_map(evidence, state, scan), 20)
    rows.append(("mapping, 40 x 40 cells", t_seed, t_ours))
    t_seed = best(lambda: seed_measurement_function(state, evidence), 3)
    t_ours = best(lambda: lab.measurement_function(state, evidence), 20)
    rows.append(("36 predicted ranges (new map each call)", t_seed, t_ours))
    ev_grid = lab._as_grid(evidence)
    t_ours = best(lambda: lab.measurement_function(state, ev_grid), 50)
    rows.append(("36 predicted ranges (cached grid)", rows[-1][1], t_ours))
    prior = (state, np.diag([0.01, 0.01, 0.001]), np.diag([1e-4, 1e-4, 0.08]), np.eye(36))
    t_step = best(lambda: lab.ekf_mapping_step(prior, evidence, 1.0, 0.1, scan, 0.1), 10)

    print(f"{'operation':42s} {'seed loop [ms]':>15s} {'robolab [ms]':>13s} {'speed-up':>9s}")
    for name, a, b in rows:
        print(f"{name:42s} {a * 1e3:15.2f} {b * 1e3:13.3f} {a / b:8.0f}x")
    print(f"{'one ekf_mapping_step (predict, map, correct)':42s} {'':15s} {t_step * 1e3:13.3f}")


if __name__ == "__main__":
    main()
