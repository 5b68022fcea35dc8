"""Benchmark: one predict-weight-resample step of the lab 03 particle filter.

Measures ``move_particles`` + ``measurement_probability`` + ``low_variance_resample``
(solutions.landmark_pf) on 100,000 particles, pinned to one core, against a
baseline measured in the same run: the same step written per particle in plain
Python (the seed's MATLAB structure: one cRobot-style move and weight per
particle, Table 4.4 as a while loop), timed on a subset and scaled linearly.

Target (issue 7): under 50 ms per step for 100,000 particles on one core.

Run: ``python benchmarks/landmark_pf.py``
"""

from __future__ import annotations

import math

import timing  # before numpy: one BLAS thread

# isort: split
import numpy as np

from robolab.world import LANDMARKS
from solutions.landmark_pf import low_variance_resample, measurement_probability, move_particles

N = timing.sized(100_000, 100)
BASELINE_N = timing.sized(2_000, 10)
U = (np.pi / 4, 20.0)
NOISE = (5.0, 0.1, 5.0)  # forward, turn, sensor: seed section g


def step_vectorized(particles, z, rng):
    p = move_particles(particles, U[0], U[1], NOISE[0], NOISE[1], rng)
    w = measurement_probability(z, p, LANDMARKS, NOISE[2])
    return low_variance_resample(p, w, rng)


def step_python_loop(particles, z, rng):
    """The same step, one particle at a time (the baseline)."""
    n = len(particles)
    size, (fwd, turn, sig) = 100.0, NOISE
    moved, weights = [], []
    for x, y, th in particles.tolist():
        th = th + U[0] + rng.normal(0.0, turn)
        th = (th + math.pi) % (2 * math.pi) - math.pi
        d = U[1] + rng.normal(0.0, fwd)
        x, y = (x + d * math.cos(th)) % size, (y + d * math.sin(th)) % size
        w = 1.0
        for (lx, ly), zk in zip(LANDMARKS.tolist(), z.tolist(), strict=True):
            e = zk - math.hypot(x - lx, y - ly)
            w *= math.exp(-0.5 * (e / sig) ** 2) / (math.sqrt(2 * math.pi) * sig)
        moved.append((x, y, th))
        weights.append(w)
    total = sum(weights)
    r, c, i, out = rng.uniform(0.0, 1.0 / n), weights[0] / total, 0, []
    for m in range(n):
        u = r + m / n
        while u > c and i < n - 1:
            i += 1
            c += weights[i] / total
        out.append(moved[i])
    return np.array(out)


def main():
    pinned = timing.pin_to_one_core()
    rng = np.random.default_rng(0)
    cloud = np.column_stack(
        [rng.normal(50, 5, N), rng.normal(50, 5, N), rng.uniform(-np.pi, np.pi, N)]
    )
    z = np.hypot(*(np.array([62.0, 64.0]) - LANDMARKS).T)
    step_vectorized(cloud, z, np.random.default_rng(1))  # warm-up
    t_vec = timing.best_of(step_vectorized, 15, cloud, z, np.random.default_rng(2)).wall
    t_loop_subset = timing.best_of(
        step_python_loop, 3, cloud[:BASELINE_N], z, np.random.default_rng(3)
    ).wall
    t_loop = t_loop_subset * N / BASELINE_N

    print(
        f"lab 03 particle filter: one predict-weight-resample step, N = {N:,} particles ({pinned})"
    )
    print(f"{'implementation':<48}{'ms / step':>12}{'particles / s':>16}{'speed-up':>10}")
    print(
        f"{'per-particle Python loop (' + f'{BASELINE_N:,} timed, scaled)':<48}"
        f"{t_loop * 1e3:>12.1f}{N / t_loop:>16,.0f}{1.0:>10.1f}"
    )
    print(
        f"{'vectorized numpy (solutions.landmark_pf)':<48}{t_vec * 1e3:>12.1f}{N / t_vec:>16,.0f}"
        f"{t_loop / t_vec:>10.1f}"
    )
    print(f"target < 50 ms per step: {'met' if t_vec < 0.05 else 'NOT met'}")


if __name__ == "__main__":
    main()
