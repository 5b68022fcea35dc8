"""Benchmark: EKF-SLAM steps per second against the number of landmarks, on one core.

One step is ``predict`` (unicycle) and ``correct`` with 3 observations, on a
mapped state of K landmarks with a full, correlated covariance (the situation
after a loop: every landmark correlated with every other). The reference
(``solutions.ekf_slam``) touches only the pose rows in the prediction (O(K))
and changes all (3 + 2K)^2 entries of Sigma in the correction (O(K^2)): one step
should cost about 4x more when K doubles, once K is large enough that the
covariance update, not numpy's per-call overhead, dominates.

Baseline, measured in the same run (interleaved, best of 3 by process CPU time):
the book's Table 10.1 written with dense matrices: the full (3 + 2K)^2 Jacobian
G in ``G Sigma G^T``, and ``(I - K H) Sigma`` with the full identity: O(K^3) per
step. It is timed up to K = 200 (one step there already takes a tenth of a second).

Run: ``python benchmarks/ekf_slam.py``
"""

from __future__ import annotations

import timing  # before numpy: one BLAS thread

# isort: split
import numpy as np

from robolab.geometry import wrap_angle
from solutions.ekf_slam import _observe, correct, predict

KS = timing.sized((5, 10, 25, 50, 100, 200, 400), (5, 10))
DENSE_MAX_K = 200
REPEATS = timing.sized(3, 1)
N_OBS = 3
R = np.diag([0.02**2, 0.02**2, np.deg2rad(0.5) ** 2])
QT = np.diag([0.1**2, np.deg2rad(2.0) ** 2])


def mapped_state(k, rng):
    """Robot at the origin, K landmarks within 10 m, a random correlated covariance."""
    n = 3 + 2 * k
    mu = np.concatenate([[0.0, 0.0, 0.1], rng.uniform(-10, 10, 2 * k)])
    a = rng.normal(size=(n, n)) * 0.05
    return mu, a @ a.T / n + 0.01 * np.eye(n)


def workload(k, steps, rng):
    """``steps`` (command, observations) pairs: 3 observations of random landmarks per step."""
    out = []
    for _ in range(steps):
        ids = rng.choice(k, size=min(N_OBS, k), replace=False)
        z = np.column_stack([rng.uniform(1, 10, len(ids)), rng.uniform(-1, 1, len(ids)), ids])
        out.append((np.array([1.0, 0.1]), z))
    return out


def run_reference(mu, sigma, steps):
    for u, z in steps:
        mu, sigma = predict(mu, sigma, u, R, dt=0.1)
        mu, sigma = correct(mu, sigma, z, QT)
    return mu


def run_dense(mu, sigma, steps):
    """Table 10.1 with dense matrices: full G and (I - K H) products, O(K^3) per step."""
    n = len(mu)
    F = np.zeros((3, n))
    F[:, :3] = np.eye(3)
    for (v, w), z in steps:
        th = mu[2]
        mu = mu + F.T @ np.array([v * 0.1 * np.cos(th), v * 0.1 * np.sin(th), w * 0.1])
        G = np.eye(n)
        G[0, 2], G[1, 2] = -v * 0.1 * np.sin(th), v * 0.1 * np.cos(th)
        sigma = G @ sigma @ G.T + F.T @ R @ F
        z_hat, H = _observe(mu, z[:, 2].astype(np.intp))
        H = H.reshape(-1, n)
        e = (z[:, :2] - z_hat).ravel()
        e[1::2] = wrap_angle(e[1::2])
        S = H @ sigma @ H.T + np.kron(np.eye(len(z)), QT)
        K = sigma @ H.T @ np.linalg.inv(S)
        mu = mu + K @ e
        sigma = (np.eye(n) - K @ H) @ sigma
    return mu


def main():
    pinned = timing.pin_to_one_core()
    rng = np.random.default_rng(0)
    print(f"lab 08 EKF-SLAM: one step = predict + correct with {N_OBS} observations ({pinned})")
    print(
        f"{'K':>5}{'state n':>9}{'reference ms/step':>19}{'steps/s':>10}{'x per 2x K':>12}"
        f"{'dense ms/step':>15}{'reference speed-up':>20}"
    )
    previous = None
    for k in KS:
        mu, sigma = mapped_state(k, rng)
        steps = workload(k, timing.sized(40 if k <= 100 else 10, 2), rng)
        fns = {"reference": lambda mu=mu, sigma=sigma, s=steps: run_reference(mu, sigma, s)}
        dense_steps = steps[: 10 if k <= 50 else 3]
        if k <= DENSE_MAX_K:
            fns["dense"] = lambda mu=mu, sigma=sigma, s=dense_steps: run_dense(mu, sigma, s)
        best = timing.interleaved(fns, REPEATS)
        ref = best["reference"] / len(steps)
        dense = best["dense"] / len(dense_steps) if "dense" in best else float("nan")
        growth = ""
        if previous is not None:  # the cost ratio scaled to one doubling of K
            growth = f"{(ref / previous[1]) ** (np.log(2) / np.log(k / previous[0])):.1f}"
        print(
            f"{k:>5}{3 + 2 * k:>9}{1e3 * ref:>19.3f}{1 / ref:>10.0f}{growth:>12}"
            f"{1e3 * dense:>15.3f}{dense / ref:>20.1f}"
        )
        previous = (k, ref)
    print(f"({timing.load_average()}; 'x per 2x K': cost ratio per doubling of K, 4 = quadratic)")


if __name__ == "__main__":
    main()
