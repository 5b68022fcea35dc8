"""Benchmark: FastSLAM 1.0 steps per second, 100 particles x 15 landmarks, on one core.

Replays the first 300 steps of the fiducial robot with 15 fiducials
(``FiducialRobot(seed=0, n_fiducials=15)``, about 3.6 observations per step)
through ``solutions.fastslam.fastslam_step`` (vectorized over particles and
over the observations of a step), starting from a state in which every landmark
is already mapped, so each observation is a full EKF update.

Baseline, measured in the same run: the same step written the way the seed's
MATLAB reads, one particle at a time and one observation at a time, each a
2 x 2 EKF update in numpy (predict, update, weight, normalize, low-variance
resample), timed on the first 60 steps.

Speeds are best of 3 repetitions, by process CPU time (steadier than wall
clock on a shared machine) and by wall clock. Target (issue 11): >= 200 steps
per second on one core.

A second, larger workload: 1000 particles x 100 landmarks
(``FiducialRobot(seed=0, n_fiducials=100)``, about 22 observations per step), 100
steps from a mapped state. Its baseline, measured in the same run (interleaved,
best of 3 by CPU time), is the same step with the EKF update written with
numpy's batched ``@`` on stacks of 2 x 2 matrices (how ``_ekf_update`` was
written before its products were spelled out entry by entry), new arrays copied
into the step's (the spelled-out update works in place). Target (issue 29):
>= 300 steps per second on one core.

Run: ``python benchmarks/fastslam.py``
"""

from __future__ import annotations

import timing  # before numpy: one BLAS thread

# isort: split
import numpy as np

from robolab.fiducials import FiducialRobot
from robolab.geometry import wrap_angle
from solutions import fastslam as fs
from solutions.fastslam import fastslam_step, init_particles

M = timing.sized(100, 5)
K = 15
STEPS = timing.sized(300, 10)
BASELINE_STEPS = timing.sized(60, 3)
TARGET = 200.0  # steps per second


def mapped_state(run, rng):
    """A state with every landmark mapped near its true position (0.2 m std), particles near x0."""
    s = init_particles(M, K, run.x0, init="prior")
    s["means"] = run.fiducials[None] + rng.normal(0.0, 0.2, (M, K, 2))
    s["covs"][:] = 0.04 * np.eye(2)
    s["poses"] = run.x0 + rng.normal(0.0, [0.05, 0.05, 0.01], (M, 3))
    return s


def run_vectorized(state, steps, rng):
    for u, z in steps:
        state = fastslam_step(state, u, z, RUN.Q, RUN.Qt, rng, dt=RUN.dt)
    return state


def run_python_loop(state, steps, rng):
    """The baseline: loops over particles and observations, small numpy arrays inside."""
    poses = [p.copy() for p in state["poses"]]
    means = [[m.copy() for m in particle] for particle in state["means"]]
    covs = [[c.copy() for c in particle] for particle in state["covs"]]
    chol, Qt, dt = np.linalg.cholesky(RUN.Q), RUN.Qt, RUN.dt
    for (v, om), z in steps:
        weights = np.ones(M)
        for k in range(M):
            x, y, th = poses[k]
            noise = chol @ rng.standard_normal(3)
            poses[k] = (
                np.array(
                    [x + v * dt * np.cos(th), y + v * dt * np.sin(th), wrap_angle(th + om * dt)]
                )
                + noise
            )
            for r, b, j in z:
                j = int(j)
                mu, P = means[k][j], covs[k][j]
                d = mu - poses[k][:2]
                q = d @ d
                zhat = np.array([np.sqrt(q), wrap_angle(np.arctan2(d[1], d[0]) - poses[k][2])])
                H = np.array([[d[0] / np.sqrt(q), d[1] / np.sqrt(q)], [-d[1] / q, d[0] / q]])
                S = H @ P @ H.T + Qt
                S_inv = np.linalg.inv(S)
                K_gain = P @ H.T @ S_inv
                e = np.array([r, b]) - zhat
                e[1] = wrap_angle(e[1])
                means[k][j] = mu + K_gain @ e
                covs[k][j] = (np.eye(2) - K_gain @ H) @ P
                weights[k] *= np.exp(-0.5 * e @ S_inv @ e) / np.sqrt(np.linalg.det(2 * np.pi * S))
        if len(z):
            weights /= weights.sum()
            pointers = rng.uniform(0, 1 / M) + np.arange(M) / M
            idx = np.minimum(np.searchsorted(np.cumsum(weights), pointers), M - 1)
            poses = [poses[i].copy() for i in idx]
            means = [[m.copy() for m in means[i]] for i in idx]
            covs = [[c.copy() for c in covs[i]] for i in idx]
    return poses


RUN = FiducialRobot(seed=0, n_fiducials=K, n_steps=STEPS).to_run()
BIG_M, BIG_K, BIG_STEPS, BIG_TARGET = timing.sized(1000, 5), 100, timing.sized(100, 3), 300.0


def ekf_update_matmul(mu, sigma, zz, p, qt):
    """The EKF update with batched ``@`` products (the large workload's baseline)."""
    zhat = fs._range_bearing(mu, p)
    H = fs._range_bearing_jacobian(mu, p)
    Ht = np.swapaxes(H, -1, -2)
    PHt = sigma @ Ht
    S = H @ PHt + qt
    S_inv, logdet_S = fs._inv2(S)  # the log-determinant: no overflow for tiny or huge S
    K_gain = PHt @ S_inv
    e = zz - zhat
    e = np.concatenate([e[..., :1], wrap_angle(e[..., 1:2])], -1)
    new_mean = mu + (K_gain @ e[..., None])[..., 0]
    new_cov = sigma - K_gain @ H @ sigma
    new_cov = 0.5 * (new_cov + np.swapaxes(new_cov, -1, -2))
    maha = np.einsum("...i,...ij,...j->...", e, S_inv, e)
    return new_mean, new_cov, -0.5 * maha - np.log(2.0 * np.pi) - 0.5 * logdet_S


def blocked_matmul(means, covs, z, poses, qt, log_like):
    """:func:`ekf_update_matmul` in place of the step's ``_blocked_ekf_update`` (same arguments)."""
    means[...], covs[...], log_like[...] = ekf_update_matmul(
        means, covs, z[None], poses[:, None, :], qt
    )


def big_workload():
    """Steps/s (CPU) of the spelled-out and the batched-@ EKF update, 1000 x 100, interleaved."""

    run = FiducialRobot(seed=0, n_fiducials=BIG_K, n_steps=BIG_STEPS).to_run()
    steps = [(run.commands[t], run.observations(t)) for t in range(BIG_STEPS)]
    rng = np.random.default_rng(5)
    state = init_particles(BIG_M, BIG_K, run.x0, init="prior")
    state["means"] = run.fiducials[None] + rng.normal(0.0, 0.2, (BIG_M, BIG_K, 2))
    state["covs"][:] = 0.04 * np.eye(2)
    state["seen"][:] = True
    state["poses"] = run.x0 + rng.normal(0.0, [0.05, 0.05, 0.01], (BIG_M, 3))

    def replay(update):
        original = fs._blocked_ekf_update
        fs._blocked_ekf_update = update
        try:
            s, r = state, np.random.default_rng(6)
            for u, z in steps:
                s = fastslam_step(s, u, z, run.Q, run.Qt, r, dt=run.dt)
            return s
        finally:
            fs._blocked_ekf_update = original

    a, b = replay(fs._blocked_ekf_update), replay(blocked_matmul)  # warm-up; same filter
    assert np.allclose(a["means"], b["means"], atol=1e-9) and np.allclose(a["poses"], b["poses"])
    best = timing.interleaved(
        {
            "spelled out": lambda: replay(fs._blocked_ekf_update),
            "batched @": lambda: replay(blocked_matmul),
        },
        3,
    )
    n_obs = sum(len(z) for _, z in steps) / BIG_STEPS
    return best, n_obs


def main():
    pinned = timing.pin_to_one_core()
    steps = [(RUN.commands[t], RUN.observations(t)) for t in range(STEPS)]
    n_obs = sum(len(z) for _, z in steps) / STEPS
    state = mapped_state(RUN, np.random.default_rng(0))
    run_vectorized(state, steps[:20], np.random.default_rng(1))  # warm-up
    t_vec = timing.best_of(run_vectorized, 3, state, steps, np.random.default_rng(2))
    t_loop = timing.best_of(
        run_python_loop, 3, state, steps[:BASELINE_STEPS], np.random.default_rng(3)
    )
    vec = STEPS / t_vec.cpu, STEPS / t_vec.wall
    loop = BASELINE_STEPS / t_loop.cpu, BASELINE_STEPS / t_loop.wall

    print(
        f"lab 07 FastSLAM: fastslam_step, M = {M} particles x K = {K} landmarks, "
        f"{n_obs:.1f} observations per step ({pinned})"
    )
    print(
        f"{'implementation':<44}{'steps/s (CPU)':>15}{'steps/s (wall)':>16}"
        f"{'ms/step (CPU)':>15}{'speed-up':>10}"
    )
    print(
        f"{'per-particle Python loop (baseline)':<44}{loop[0]:>15.1f}{loop[1]:>16.1f}"
        f"{1e3 / loop[0]:>15.2f}{1.0:>10.1f}"
    )
    print(
        f"{'vectorized numpy (solutions.fastslam)':<44}{vec[0]:>15.1f}{vec[1]:>16.1f}"
        f"{1e3 / vec[0]:>15.2f}"
        f"{vec[0] / loop[0]:>10.1f}"
    )
    print(
        f"target >= {TARGET:.0f} steps per second on one core: "
        f"{'met' if vec[0] >= TARGET else 'NOT met'}"
    )
    best, n_obs = big_workload()
    print()
    print(
        f"fastslam_step, M = {BIG_M} particles x K = {BIG_K} landmarks, {n_obs:.1f} observations"
        f" per step, {BIG_STEPS} steps ({timing.load_average()})"
    )
    print(f"{'EKF update':<44}{'steps/s (CPU)':>15}{'ms/step (CPU)':>15}{'speed-up':>10}")
    base = best["batched @"]
    for name, sec in best.items():
        print(
            f"{name:<44}{BIG_STEPS / sec:>15.1f}{sec / BIG_STEPS * 1e3:>15.2f}{base / sec:>10.2f}"
        )
    rate = BIG_STEPS / best["spelled out"]
    print(
        f"target >= {BIG_TARGET:.0f} steps per second on one core: "
        f"{'met' if rate >= BIG_TARGET else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
