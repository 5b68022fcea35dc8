"""Visible checks for lab 07, FastSLAM 1.0 with known correspondences.

Quick, friendly and weaker than the hidden tests: shapes, one worked example
and one invariant per exercise.
"""

from __future__ import annotations

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_shape

__all__ = [
    "check_init_particles",
    "check_predict_poses",
    "check_h",
    "check_h_jacobian",
    "check_update_landmark",
    "check_fastslam_step",
    "check_fastslam",
]

_QT = np.diag([0.1**2, np.deg2rad(2.0) ** 2])
_KEYS = ("poses", "means", "covs", "seen", "weights")


def _keys(what, state):
    if not isinstance(state, dict):
        raise CheckFailed(f"{what}: expected a dict with keys {_KEYS}, got {type(state).__name__}")
    missing = [k for k in _KEYS if k not in state]
    if missing:
        raise CheckFailed(f"{what}: the state dict is missing {', '.join(missing)}")


@check
def check_init_particles(init_particles) -> None:
    """3 particles, 2 landmarks: shapes, the vague prior; first-observation init sees nothing."""
    s = init_particles(3, 2, [-2.5, -2.0, 0.25], init="prior")
    _keys("init_particles(3, 2, x0)", s)
    poses = expect_shape("poses", s["poses"], (3, 3))
    expect_close("every particle's pose", poses, np.tile([-2.5, -2.0, 0.25], (3, 1)))
    expect_close("means (the vague prior's mu0 = 0)", s["means"], np.zeros((3, 2, 2)))
    expect_close(
        "covs (the vague prior's Sigma0 = 10000 I)",
        s["covs"],
        np.broadcast_to(1e4 * np.eye(2), (3, 2, 2, 2)),
    )
    expect_close("weights", s["weights"], np.full(3, 1 / 3))
    if not np.all(np.asarray(s["seen"], dtype=bool)):
        raise CheckFailed(
            "with init='prior' every landmark already has a (vague) belief: seen should be all True"
        )
    s = init_particles(3, 2, [0.0, 0.0, 0.0], init="first_observation")
    if np.any(np.asarray(s["seen"], dtype=bool)):
        raise CheckFailed(
            "with init='first_observation' no landmark has been seen yet: seen should be all False"
        )


@check
def check_predict_poses(predict_poses) -> None:
    """Without noise a particle at (0, 0, 0) driving 1 m/s for 0.1 s ends at (0.1, 0, omega dt)."""
    rng = np.random.default_rng(0)
    got = predict_poses(np.zeros((2, 3)), [1.0, 0.5], np.zeros((3, 3)), rng, dt=0.1)
    expect_close("predict_poses with Q = 0", got, [[0.1, 0.0, 0.05], [0.1, 0.0, 0.05]])
    cloud = np.asarray(
        predict_poses(np.zeros((500, 3)), [1.0, 0.0], np.diag([1e-2, 1e-2, 1e-4]), rng, dt=0.1)
    )
    spread = cloud[:, 0].std()
    if not 0.08 < spread < 0.12:
        raise CheckFailed(
            f"with Q[0, 0] = 0.01 the x spread should be about 0.1 m, got {spread:.3f} m "
            "(Q is a covariance: sample with its square root)"
        )


@check
def check_h(h) -> None:
    """A landmark at (3, 4) seen from the origin: range 5 m, bearing atan2(4, 3)."""
    expect_close(
        "h([3, 4], [0, 0, 0])",
        h(np.array([3.0, 4.0]), np.array([0.0, 0.0, 0.0])),
        [5.0, np.arctan2(4, 3)],
    )
    got = np.asarray(h(np.array([-1.0, -0.01]), np.array([0.0, 0.0, 0.5])), dtype=float)
    if not -np.pi <= got[1] <= np.pi:
        raise CheckFailed(f"the bearing must be wrapped to [-pi, pi), got {got[1]:.3f}")


@check
def check_h_jacobian(h_jacobian) -> None:
    """The Jacobian for a landmark at (3, 4) seen from the origin."""
    expect_close(
        "h_jacobian([3, 4], [0, 0, 0])",
        h_jacobian(np.array([3.0, 4.0]), np.array([0.0, 0.0, 0.0])),
        [[0.6, 0.8], [-4 / 25, 3 / 25]],
    )


@check
def check_update_landmark(update_landmark) -> None:
    """Believed 5 m ahead, measured 6 m: it moves forward; bearings 3.1 and -3.1 are close."""
    new_mean, new_cov, log_like = update_landmark(
        np.array([5.0, 0.0]), np.eye(2), np.array([6.0, 0.0]), np.array([0.0, 0.0, 0.0]), _QT
    )
    gain = 1.0 / (1.0 + _QT[0, 0])
    expect_close("updated mean", new_mean, [5.0 + gain, 0.0])
    expect_shape("updated covariance", new_cov, (2, 2))
    if not np.isfinite(float(np.asarray(log_like))):
        raise CheckFailed(f"the log-likelihood must be a finite number, got {log_like}")
    mean = 5.0 * np.array([np.cos(-3.1), np.sin(-3.1)])
    moved, _, _ = update_landmark(
        mean, 0.25 * np.eye(2), np.array([5.0, 3.1]), np.array([0.0, 0.0, 0.0]), _QT
    )
    jump = float(np.hypot(*(np.asarray(moved, dtype=float) - mean)))
    if jump > 0.5:
        raise CheckFailed(
            f"measured bearing 3.1, predicted -3.1 (0.08 rad apart) "
            f"moved the landmark {jump:.1f} m: "
            "wrap the bearing error to [-pi, pi)"
        )


@check
def check_fastslam_step(fastslam_step) -> None:
    """Four particles, one observation: shapes, normalized weights, observed landmark updated."""
    state = {
        "poses": np.zeros((4, 3)),
        "means": np.tile([[4.0, 0.0], [0.0, 3.0]], (4, 1, 1))
        + np.array([0.0, 0.1, 0.2, 0.3])[:, None, None],
        "covs": np.broadcast_to(0.1 * np.eye(2), (4, 2, 2, 2)).copy(),
        "seen": np.ones((4, 2), dtype=bool),
        "weights": np.full(4, 0.25),
    }
    out = fastslam_step(
        state,
        np.array([0.0, 0.0]),
        np.array([[4.0, 0.0, 0.0]]),
        np.zeros((3, 3)),
        _QT,
        np.random.default_rng(0),
        dt=0.1,
        resample=False,
    )
    _keys("fastslam_step", out)
    expect_shape("poses", out["poses"], (4, 3))
    means = expect_shape("means", out["means"], (4, 2, 2))
    w = expect_shape("weights", out["weights"], (4,))
    if not (np.all(np.isfinite(w)) and abs(w.sum() - 1) < 1e-9):
        raise CheckFailed(f"weights must be finite and sum to 1, got {w}")
    if not w[0] > w[3]:
        raise CheckFailed(
            f"the particle whose landmark matches the measurement should weigh most, got {w}"
        )
    expect_close("landmark 1 (not observed)", means[:, 1], state["means"][:, 1])


@check
def check_fastslam(fastslam) -> None:
    """Ten seconds of the fiducial robot, 20 particles: the path stays within 0.5 m of the truth."""
    from robolab.fiducials import FiducialRobot

    run = FiducialRobot(seed=0, n_steps=100).to_run()
    out = fastslam(run, 20, np.random.default_rng(0))
    path = expect_shape("path", out["path"], (101, 3))
    err = float(np.max(np.hypot(*(path[:, :2] - run.true_poses[:, :2]).T)))
    if err > 0.5:
        raise CheckFailed(
            f"the estimated path strays {err:.2f} m from the true one (expected < 0.5 m)"
        )
    expect_shape("landmarks", out["landmarks"], (5, 2))
