"""Visible checks for lab 08, EKF-SLAM with known correspondences.

Quick, friendly and weaker than the hidden tests: shapes, one worked example
and one invariant per exercise.
"""

from __future__ import annotations

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_shape

__all__ = [
    "check_predict",
    "check_observation",
    "check_correct",
    "check_add_landmark",
    "check_ekf_slam",
]

_QT = np.diag([0.1**2, np.deg2rad(2.0) ** 2])


@check
def check_predict(predict) -> None:
    """Robot at the origin drives 1 m/s for 0.1 s: the pose moves, the landmark block does not."""
    mu = np.array([0.0, 0.0, 0.0, 3.0, 4.0])
    sigma = np.diag([0.0, 0.0, 0.1, 1.0, 1.0])
    before = sigma.copy()
    new_mu, new_sigma = predict(mu, sigma, [1.0, 0.5], np.diag([1e-4, 1e-4, 1e-4]), dt=0.1)
    expect_close("predicted mean", new_mu, [0.1, 0.0, 0.05, 3.0, 4.0])
    new_sigma = expect_shape("predicted covariance", new_sigma, (5, 5))
    # G_x = [[1, 0, 0], [0, 1, 0.1], [0, 0, 1]]: heading variance 0.1 leaks into y by (0.1)^2
    expect_close("predicted Sigma[1, 1] (0.1 * 0.1^2 + 1e-4)", new_sigma[1, 1], 0.1 * 0.01 + 1e-4)
    expect_close("the landmark block (unchanged)", new_sigma[3:, 3:], np.eye(2))
    if not np.array_equal(sigma, before):
        raise CheckFailed("predict changed the sigma passed in: work on a copy")


@check
def check_observation(observation) -> None:
    """A landmark at (3, 4) seen from the origin: range 5 m, bearing atan2(4, 3), H 2 x 5."""
    z, H = observation(np.array([0.0, 0.0, 0.0, 3.0, 4.0]), 0)
    expect_close("z_hat", z, [5.0, np.arctan2(4, 3)])
    expect_close(
        "H", H, [[-0.6, -0.8, 0.0, 0.6, 0.8], [4 / 25, -3 / 25, -1.0, -4 / 25, 3 / 25]]
    )


@check
def check_correct(correct) -> None:
    """Believed 5 m ahead, measured 6 m: it moves forward; bearings 3.1 and -3.1 are close."""
    mu = np.array([0.0, 0.0, 0.0, 5.0, 0.0])
    sigma = np.diag([0.0, 0.0, 0.0, 1.0, 1.0])
    new_mu, new_sigma = correct(mu, sigma, np.array([[6.0, 0.0, 0.0]]), _QT)
    gain = 1.0 / (1.0 + _QT[0, 0])
    expect_close("corrected mean", new_mu, [0.0, 0.0, 0.0, 5.0 + gain, 0.0])
    new_sigma = expect_shape("corrected covariance", new_sigma, (5, 5))
    if not np.allclose(new_sigma, new_sigma.T):
        raise CheckFailed("the corrected covariance must be symmetric")
    behind = np.array([0.0, 0.0, 0.0, *(5.0 * np.array([np.cos(-3.1), np.sin(-3.1)]))])
    moved, _ = correct(behind, 0.25 * np.diag([0.0, 0.0, 0.0, 1.0, 1.0]),
                       np.array([[5.0, 3.1, 0.0]]), _QT)
    jump = float(np.hypot(*(np.asarray(moved, dtype=float)[3:] - behind[3:])))
    if jump > 0.5:
        raise CheckFailed(
            f"measured bearing 3.1, predicted -3.1 (0.08 rad apart) moved the landmark "
            f"{jump:.1f} m: wrap the bearing innovation to [-pi, pi)"
        )


@check
def check_add_landmark(add_landmark) -> None:
    """A robot known exactly at (1, 2) facing +y sees a landmark 2 m to its right: (3, 2)."""
    mu = np.array([1.0, 2.0, np.pi / 2, 0.0, 0.0])
    new_mu, new_sigma = add_landmark(mu, np.zeros((5, 5)), [2.0, -np.pi / 2], 0, _QT)
    expect_close("mean", new_mu, [1.0, 2.0, np.pi / 2, 3.0, 2.0])
    new_sigma = expect_shape("covariance", new_sigma, (5, 5))
    expect_close("the new landmark's covariance G_z Qt G_z^T", new_sigma[3:, 3:],
                 np.diag([_QT[0, 0], 4 * _QT[1, 1]]), atol=1e-12)


@check
def check_ekf_slam(ekf_slam) -> None:
    """Ten seconds of the fiducial robot: the path stays within 0.3 m of the truth."""
    from robolab.fiducials import FiducialRobot

    run = FiducialRobot(seed=0, n_steps=100).to_run()
    out = ekf_slam(run)
    path = expect_shape("path", out["path"], (101, 3))
    err = float(np.max(np.hypot(*(path[:, :2] - run.true_poses[:, :2]).T)))
    if err > 0.3:
        raise CheckFailed(
            f"the estimated path strays {err:.2f} m from the true one (expected < 0.3 m)"
        )
    expect_shape("landmarks", out["landmarks"], (5, 2))
