"""Hidden tests for lab 07, FastSLAM 1.0 with known correspondences (seed 003). 100 points.

Every test calls only ``lab.<exercise>(...)`` with plain data (arrays, dicts of
arrays, a :class:`robolab.fiducials.FiducialRun`) and a fresh
``np.random.default_rng(seed)`` per call, and compares results after
``np.asarray(..., dtype=float)``, so it runs on the reference solution and,
with ``--notebook``, across the grader's process boundary.

Oracles are written here, independently of the student's code: finite
differences for the Jacobian, a textbook Kalman update with ``np.linalg.inv``
and ``scipy.stats.multivariate_normal`` for the landmark update, and a compact
FastSLAM (:func:`_variant_fastslam`) whose two broken variants (no bearing
wrap, the handout's weight formula) prove that the end-to-end bounds are not
vacuous: the accuracy test asserts that both variants miss them.

Points: init_particles 8, predict_poses 12, h 8, h_jacobian 12,
update_landmark 20, fastslam_step 24, fastslam 16.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from robolab.checks.base import angle_error
from robolab.fiducials import FiducialRobot

requires = pytest.mark.requires
#: CPU seconds the reference solution's worker uses while graded (loading and every call,
#: children included: `cpu_seconds` of the correct example in `make grade`'s gradebook.json,
#: 2026-12-02): a submission gets 8 times that in total, at least 20 s (docs/grading.md).
REFERENCE_CPU_SECONDS = 3.5

#: Exercises each exercise is likely to call (the feedback names them when they fail).
USES = {
    "fastslam_step": ["predict_poses", "update_landmark", "h", "h_jacobian"],
    # through fastslam_step: its end-to-end test waits for their core tests too
    "fastslam": ["init_particles", "fastslam_step", "predict_poses", "update_landmark"],
}
QT = np.diag([0.1**2, np.deg2rad(2.0) ** 2])


def _f(x):
    return np.asarray(x, dtype=float)


def _wrap(a):
    return (np.asarray(a, dtype=float) + np.pi) % (2 * np.pi) - np.pi


def _h(lm, pose):
    """The test's own measurement model, for finite differences and oracles."""
    d = np.asarray(lm, float)[..., :2] - np.asarray(pose, float)[..., :2]
    return np.stack(
        [np.hypot(d[..., 0], d[..., 1]), _wrap(np.arctan2(d[..., 1], d[..., 0]) - pose[..., 2])], -1
    )


def _kalman(mean, cov, z, pose, Qt):
    """Textbook EKF landmark update (Probabilistic Robotics Table 13.1, lines 12-19)."""
    d = mean - pose[:2]
    q = d @ d
    H = np.array([[d[0] / np.sqrt(q), d[1] / np.sqrt(q)], [-d[1] / q, d[0] / q]])
    zhat = _h(mean, pose)
    S = H @ cov @ H.T + Qt
    K = cov @ H.T @ np.linalg.inv(S)
    e = z - zhat
    e[1] = _wrap(e[1])
    return mean + K @ e, (np.eye(2) - K @ H) @ cov, multivariate_normal(zhat, S).logpdf(zhat + e)


def _random_spd(rng, n, scale):
    a = rng.normal(size=(n, 2, 2)) * scale
    return a @ np.swapaxes(a, 1, 2) + 0.05 * scale**2 * np.eye(2)


def _state(poses, means, covs, seen, weights=None):
    m = len(poses)
    return {
        "poses": _f(poses),
        "means": _f(means),
        "covs": _f(covs),
        "seen": np.asarray(seen, dtype=bool),
        "weights": np.full(m, 1.0 / m) if weights is None else _f(weights),
    }


# -- init_particles: 8 ---------------------------------------------------------------


@pytest.mark.grades("init_particles", points=4)
def test_init_particles_prior_is_the_seeds_setup(lab):
    """init='prior': every particle at x0, every landmark N(0, 10^4 I) and seen, weights 1/M."""
    x0 = [-2.5, -2.0, 0.25]
    s = lab.init_particles(7, 5, x0, init="prior")
    np.testing.assert_allclose(
        _f(s["poses"]), np.tile(x0, (7, 1)), err_msg="every particle must start at x0"
    )
    np.testing.assert_allclose(
        _f(s["means"]), np.zeros((7, 5, 2)), err_msg="init='prior': every landmark mean must be 0"
    )
    np.testing.assert_allclose(
        _f(s["covs"]),
        np.broadcast_to(10000.0 * np.eye(2), (7, 5, 2, 2)),
        err_msg="init='prior': every landmark covariance must be 10^4 I",
    )
    assert np.asarray(s["seen"], dtype=bool).shape == (7, 5) and np.all(
        np.asarray(s["seen"], dtype=bool)
    ), "init='prior': seen must be a (7, 5) array, all True"
    np.testing.assert_allclose(_f(s["weights"]), np.full(7, 1 / 7), err_msg="weights must be 1/M")


@pytest.mark.grades("init_particles", points=2)
def test_init_particles_first_observation_has_nothing_seen(lab):
    """init='first_observation': nothing seen yet; headings wrapped; weights sum to 1."""
    s = lab.init_particles(4, 3, [1.0, 2.0, 0.5], init="first_observation")
    np.testing.assert_allclose(
        _f(s["poses"]), np.tile([1.0, 2.0, 0.5], (4, 1)), err_msg="every particle must start at x0"
    )
    seen = np.asarray(s["seen"], dtype=bool)
    assert seen.shape == (4, 3) and not seen.any(), (
        "init='first_observation': seen must be (4, 3), all False"
    )
    assert _f(s["means"]).shape == (4, 3, 2) and _f(s["covs"]).shape == (4, 3, 2, 2), (
        "means (M, K, 2) and covs (M, K, 2, 2) placeholders must exist"
    )
    np.testing.assert_allclose(_f(s["weights"]).sum(), 1.0, err_msg="weights must sum to 1")
    wrapped = lab.init_particles(3, 2, [1.0, 2.0, 4.0], init="first_observation")
    np.testing.assert_allclose(
        _f(wrapped["poses"])[:, 2],
        4.0 - 2 * np.pi,
        atol=1e-12,
        err_msg="x0 heading 4.0 rad: the particles' headings are wrapped to [-pi, pi)",
    )


@pytest.mark.grades("init_particles", points=2)
def test_init_particles_particles_own_their_arrays(lab):
    """Every particle owns its arrays: changing one particle's landmark leaves the others alone."""
    s = lab.init_particles(3, 2, [0.0, 0.0, 0.0], init="prior")
    means, covs, poses = np.asarray(s["means"]), np.asarray(s["covs"]), np.asarray(s["poses"])
    means[0, 0] += 1.0  # raises on a read-only broadcast view: that is aliasing too
    covs[0, 0] += 1.0
    poses[0] += 1.0
    np.testing.assert_allclose(
        means[1, 0],
        [0.0, 0.0],
        err_msg="changing particle 0's landmark mean must not change particle 1's",
    )
    np.testing.assert_allclose(
        covs[1, 0],
        10000.0 * np.eye(2),
        err_msg="changing particle 0's landmark covariance must not change particle 1's",
    )
    np.testing.assert_allclose(
        poses[1], [0.0, 0.0, 0.0], err_msg="changing particle 0's pose must not change particle 1's"
    )


# -- predict_poses: 12 ---------------------------------------------------------------


@pytest.mark.grades("predict_poses", points=4)
def test_predict_poses_without_noise_is_the_unicycle(lab):
    """Q = 0: every particle moves by the unicycle step, heading wrapped; also one particle."""
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(-5, 5, (20, 2)), rng.uniform(-np.pi, np.pi, 20)])
    v, w, dt = 0.8, -0.6, 0.25
    one = _f(
        lab.predict_poses(
            poses[:1].copy(), [v, w], np.zeros((3, 3)), np.random.default_rng(1), dt=dt
        )
    )
    assert one.shape == (1, 3), f"one particle (1, 3) in: expected (1, 3) out, got {one.shape}"
    got = _f(
        lab.predict_poses(poses.copy(), [v, w], np.zeros((3, 3)), np.random.default_rng(1), dt=dt)
    )
    expected = np.column_stack(
        [
            poses[:, 0] + v * dt * np.cos(poses[:, 2]),
            poses[:, 1] + v * dt * np.sin(poses[:, 2]),
            _wrap(poses[:, 2] + w * dt),
        ]
    )
    assert got.shape == (20, 3), "20 particles in, 20 poses (20, 3) out"
    np.testing.assert_allclose(
        got[:, :2],
        expected[:, :2],
        atol=1e-12,
        err_msg="Q = 0: positions x + v dt cos(theta), y + v dt sin(theta)",
    )
    wrong = angle_error(got[:, 2], expected[:, 2], atol=1e-12)
    assert wrong is None, "Q = 0: heading theta + omega dt (modulo 2 pi): " + wrong


@pytest.mark.grades("predict_poses", points=6)
def test_predict_poses_noise_moments_match_Q(lab):
    # 5 standard errors from n = 40000 samples: a correct sampler fails with p < 1e-6;
    # noise scaled as a standard deviation instead of a variance misses by > 100 SE.
    """40 000 samples from one pose.

    The mean is the unicycle step, the covariance is Q (with correlations).
    """
    n = 40000
    Q = np.array([[4e-4, 1.5e-4, 0.0], [1.5e-4, 3e-4, -5e-5], [0.0, -5e-5, 2e-4]])
    pose = np.array([1.0, -2.0, 0.3])
    got = _f(
        lab.predict_poses(np.tile(pose, (n, 1)), [1.2, 0.4], Q, np.random.default_rng(2), dt=0.1)
    )
    mean = pose + [0.12 * np.cos(0.3), 0.12 * np.sin(0.3), 0.04]
    w = got - mean
    se_mean = np.sqrt(np.diag(Q) / n)
    assert np.all(np.abs(w.mean(0)) < 5 * se_mean), f"sample mean {got.mean(0)}, model {mean}"
    se_cov = np.sqrt((np.outer(np.diag(Q), np.diag(Q)) + Q**2) / n)
    cov = np.cov(w.T)
    assert np.all(np.abs(cov - Q) < 5 * se_cov), f"sample covariance\n{cov}\nmodel Q\n{Q}"


@pytest.mark.grades("predict_poses", points=2)
def test_predict_poses_wraps_heading_and_keeps_input(lab):
    """Headings 3.1 + 0.1 wrap to 3.2 - 2 pi; the poses passed in are not modified."""
    poses = np.array([[0.0, 0.0, 3.1], [1.0, 1.0, -3.1]])
    before = poses.copy()
    got = _f(
        lab.predict_poses(poses, [0.0, 1.0], np.zeros((3, 3)), np.random.default_rng(3), dt=0.1)
    )
    np.testing.assert_allclose(
        got[:, 2],
        [3.2 - 2 * np.pi, -3.0],
        atol=1e-12,
        err_msg="headings 3.1 + 0.1 and -3.1 + 0.1: wrapped to [-pi, pi)",
    )
    np.testing.assert_array_equal(
        poses, before, err_msg="predict_poses modified the poses passed in"
    )


# -- h: 8 -------------------------------------------------------------------------------


@pytest.mark.grades("h", points=5)
def test_h_known_values(lab):
    """Range and bearing by hand, including a landmark behind the robot whose bearing must wrap."""
    np.testing.assert_allclose(
        _f(lab.h([3.0, 4.0], [0.0, 0.0, 0.0])),
        [5.0, np.arctan2(4, 3)],
        atol=1e-12,
        err_msg="landmark (3, 4) from the origin facing +x: range 5, bearing atan2(4, 3)",
    )
    np.testing.assert_allclose(
        _f(lab.h([1.0, 3.0], [1.0, 1.0, np.pi / 2])),
        [2.0, 0.0],
        atol=1e-12,
        err_msg="landmark (1, 3) from (1, 1) facing +y: range 2, bearing 0",
    )
    # landmark behind the robot: atan2 - theta = -pi - 0.5 + 1e-4 must wrap to pi - 0.5 + 1e-4
    got = _f(lab.h([-1.0, -1e-4], [0.0, 0.0, 0.5]))
    np.testing.assert_allclose(
        got,
        [np.hypot(1.0, 1e-4), np.pi - 0.5 + 1e-4],
        atol=1e-9,
        err_msg="landmark behind the robot: bearing -pi - 0.5 + 1e-4 must wrap to pi - 0.5 + 1e-4",
    )


@pytest.mark.grades("h", points=3)
def test_h_is_vectorized_with_broadcasting(lab):
    """Landmarks (6, 4, 2) against poses (6, 1, 3) broadcast to (6, 4, 2) measurements."""
    rng = np.random.default_rng(4)
    lm = rng.uniform(-5, 5, (6, 4, 2))
    poses = np.column_stack([rng.uniform(-5, 5, (6, 2)), rng.uniform(-np.pi, np.pi, 6)])[:, None, :]
    got = _f(lab.h(lm.copy(), poses.copy()))
    assert got.shape == (6, 4, 2), (
        "landmarks (6, 4, 2) and poses (6, 1, 3) must broadcast to (6, 4, 2)"
    )
    np.testing.assert_allclose(
        got[..., 0],
        _h(lm, poses)[..., 0],
        atol=1e-12,
        err_msg="ranges of the broadcast measurements",
    )
    wrong = angle_error(got[..., 1], _h(lm, poses)[..., 1], atol=1e-12)
    assert wrong is None, "bearings of the broadcast measurements (modulo 2 pi): " + wrong
    assert np.all((got[..., 1] >= -np.pi) & (got[..., 1] <= np.pi)), (
        "bearings must be wrapped to [-pi, pi]"
    )


# -- h_jacobian: 12 -------------------------------------------------------------------


@pytest.mark.grades("h_jacobian", points=8)
def test_h_jacobian_matches_finite_differences(lab):
    """H = dh / dmu against central differences in the landmark's x and y at 50 random states."""
    rng = np.random.default_rng(5)
    n = 50
    poses = np.column_stack([rng.uniform(-5, 5, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    lm = poses[:, :2] + rng.uniform(0.5, 6, (n, 1)) * np.stack(
        [np.cos(a := rng.uniform(-np.pi, np.pi, n)), np.sin(a)], -1
    )
    got = _f(lab.h_jacobian(lm, poses))
    assert got.shape == (n, 2, 2), "50 landmarks and poses: H must have shape (50, 2, 2)"
    eps = 1e-6
    fd = np.empty((n, 2, 2))
    for c in range(2):  # central differences in the landmark's x and y
        step = np.zeros(2)
        step[c] = eps
        diff = _h(lm + step, poses) - _h(lm - step, poses)
        diff[:, 1] = _wrap(diff[:, 1])
        fd[:, :, c] = diff / (2 * eps)
    np.testing.assert_allclose(
        got,
        fd,
        rtol=1e-5,
        atol=1e-7,
        err_msg="H against central differences (step 1e-6) at 50 random states",
    )


@pytest.mark.grades("h_jacobian", points=4)
def test_h_jacobian_known_value_and_broadcasting(lab):
    # the seed's hints: d phi / d mu_x = -(mu_y - y) / q, d phi / d mu_y = (mu_x - x) / q
    """The Jacobian at (3, 4) seen from the origin, and broadcasting over (5, 3) landmarks."""
    np.testing.assert_allclose(
        _f(lab.h_jacobian([3.0, 4.0], [0.0, 0.0, 1.0])),
        [[0.6, 0.8], [-4 / 25, 3 / 25]],
        atol=1e-12,
        err_msg="landmark (3, 4) from the origin: [[0.6, 0.8], [-4/25, 3/25]]",
    )
    got = _f(lab.h_jacobian(np.ones((5, 3, 2)) * [2.0, 0.0], np.zeros((5, 1, 3))))
    assert got.shape == (5, 3, 2, 2), (
        "landmarks (5, 3, 2) and poses (5, 1, 3) must broadcast to (5, 3, 2, 2)"
    )
    np.testing.assert_allclose(
        got,
        np.broadcast_to([[1.0, 0.0], [0.0, 0.5]], (5, 3, 2, 2)),
        atol=1e-12,
        err_msg="landmark (2, 0) from the origin: [[1, 0], [0, 1/2]] for every broadcast entry",
    )


# -- update_landmark: 20 ----------------------------------------------------------------


@pytest.mark.grades("update_landmark", points=10)
def test_update_landmark_matches_a_hand_written_kalman_update(lab):
    """Mean, covariance and log-likelihood of 64 landmark updates equal a textbook Kalman update."""
    rng = np.random.default_rng(6)
    n = 64
    poses = np.column_stack([rng.uniform(-5, 5, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    a = rng.uniform(-np.pi, np.pi, n)
    means = poses[:, :2] + rng.uniform(1, 5, (n, 1)) * np.stack([np.cos(a), np.sin(a)], -1)
    covs = _random_spd(rng, n, 0.3)
    Qt = np.array([[0.02, 0.003], [0.003, 0.004]])
    z = _h(means + rng.normal(0, 0.3, (n, 2)), poses)
    got_mean, got_cov, got_ll = (_f(v) for v in lab.update_landmark(means, covs, z, poses, Qt))
    assert got_mean.shape == (n, 2) and got_cov.shape == (n, 2, 2) and got_ll.shape == (n,), (
        "64 updates: mean (64, 2), covariance (64, 2, 2), log-likelihood (64,)"
    )
    for i in range(n):
        m, c, ll = _kalman(means[i], covs[i], z[i], poses[i], Qt)
        np.testing.assert_allclose(
            got_mean[i],
            m,
            rtol=1e-9,
            atol=1e-10,
            err_msg="landmark mean after the update, against the textbook Kalman update",
        )
        np.testing.assert_allclose(
            got_cov[i],
            c,
            rtol=1e-7,
            atol=1e-10,
            err_msg="landmark covariance after the update, against the textbook Kalman update",
        )
        np.testing.assert_allclose(
            got_ll[i],
            ll,
            rtol=1e-9,
            atol=1e-9,
            err_msg="log-likelihood: ln N(z; z_hat, H S H^T + Qt) = -ln|2 pi Q|/2 - e^T Q^-1 e / 2",
        )


@pytest.mark.grades("update_landmark", points=6)
@requires("test_update_landmark_matches_a_hand_written_kalman_update")
def test_update_landmark_wraps_the_bearing_error(lab):
    """Bearings 3.1 measured and -3.1 predicted: the same update as the seam-free geometry.

    The bearings are 0.083 rad apart, not 6.2. Turned by pi about the robot the same
    geometry reads -0.042 and 0.042 (no wrap needed): whatever the formulas, the update
    must be the same, turned back (mean mirrored through the robot, covariance and
    likelihood unchanged). Only an unwrapped bearing error fails this check.
    """
    pose = np.array([0.5, -1.0, 0.0])
    cov = np.array([[0.25, 0.05], [0.05, 0.16]])
    for measured, predicted in ((3.1, -3.1), (-3.1, 3.1)):
        mean = pose[:2] + 5.0 * np.array([np.cos(predicted), np.sin(predicted)])
        z = np.array([5.0, measured])
        got_mean, got_cov, got_ll = (_f(v) for v in lab.update_landmark(mean, cov, z, pose, QT))
        turned = (2 * pose[:2] - mean, np.array([5.0, _wrap(measured + np.pi)]))
        ref_mean, ref_cov, ref_ll = (
            _f(v) for v in lab.update_landmark(turned[0], cov, turned[1], pose, QT)
        )
        assert np.hypot(*(got_mean - mean)) < 0.5, (
            f"bearing {measured} measured, {predicted} predicted: "
            f"the mean jumped from {mean} to {got_mean}; is the bearing error wrapped?"
        )
        what = f"bearing {measured} measured, {predicted} predicted, against the turned update"
        np.testing.assert_allclose(
            got_mean, 2 * pose[:2] - ref_mean, atol=1e-9, err_msg=f"mean: {what}"
        )
        np.testing.assert_allclose(got_cov, ref_cov, atol=1e-9, err_msg=f"covariance: {what}")
        np.testing.assert_allclose(got_ll, ref_ll, atol=1e-9, err_msg=f"log-likelihood: {what}")


@pytest.mark.grades("update_landmark", points=4)
def test_update_landmark_moves_towards_the_measurement(lab):
    # landmark believed 5 m ahead, measured 6 m ahead: the seed's e = z_hat - z would move it back
    """Believed 5 m ahead, measured 6 m ahead: the mean moves forwards by the Kalman gain."""
    mean, cov = np.array([5.0, 0.0]), np.eye(2)
    got_mean, got_cov, got_ll = (
        _f(v) for v in lab.update_landmark(mean, cov, [6.0, 0.0], [0.0, 0.0, 0.0], QT)
    )
    gain = 1.0 / (1.0 + QT[0, 0])
    np.testing.assert_allclose(
        got_mean,
        [5.0 + gain, 0.0],
        atol=1e-12,
        err_msg="mean moves by the gain 1 / (1 + sigma_r^2) towards the 6 m measurement",
    )
    np.testing.assert_allclose(
        got_cov[0, 0],
        QT[0, 0] / (1.0 + QT[0, 0]),
        atol=1e-12,
        err_msg="range variance after the update: sigma_r^2 / (1 + sigma_r^2)",
    )
    assert got_cov[1, 1] < 1.0 and np.isfinite(got_ll), (
        "the bearing variance must shrink and the log-likelihood be finite"
    )


# -- fastslam_step: 24 ------------------------------------------------------------------


@pytest.mark.grades("fastslam_step", points=5)
def test_fastslam_step_one_particle_is_predict_then_kalman(lab):
    """One particle, Q = 0: the pose is the unicycle step.

    Each observed landmark gets a Kalman update.
    """
    pose0 = np.array([1.0, 2.0, 0.4])
    means = np.array([[[4.0, 3.0], [-2.0, 5.0], [0.0, 0.0]]])
    covs = np.array([[0.3 * np.eye(2), [[0.2, 0.05], [0.05, 0.1]], 10000 * np.eye(2)]])
    state = _state([pose0], means, covs, [[True, True, True]])
    dt, u = 0.1, np.array([1.0, 0.5])
    pose1 = pose0 + [u[0] * dt * np.cos(pose0[2]), u[0] * dt * np.sin(pose0[2]), u[1] * dt]
    z = np.array([[3.2, 0.0, 0.0], [4.5, 1.9, 1.0]])
    out = lab.fastslam_step(state, u, z, np.zeros((3, 3)), QT, np.random.default_rng(7), dt=dt)
    np.testing.assert_allclose(
        _f(out["poses"]),
        [pose1],
        atol=1e-12,
        err_msg="Q = 0: the pose is the unicycle step from (1, 2, 0.4)",
    )
    for j in (0, 1):
        m, c, _ = _kalman(means[0, j], covs[0, j], z[j, :2], pose1, QT)
        np.testing.assert_allclose(
            _f(out["means"])[0, j],
            m,
            atol=1e-9,
            err_msg="landmark mean after the Kalman update at the predicted pose",
        )
        np.testing.assert_allclose(
            _f(out["covs"])[0, j],
            c,
            atol=1e-9,
            err_msg="landmark covariance after the Kalman update at the predicted pose",
        )
    np.testing.assert_allclose(
        _f(out["means"])[0, 2],
        [0.0, 0.0],
        err_msg="landmark 2 was not observed: its mean stays at the prior",
    )  # not observed: unchanged
    np.testing.assert_allclose(
        _f(out["covs"])[0, 2],
        10000 * np.eye(2),
        err_msg="landmark 2 was not observed: its covariance stays 10^4 I",
    )
    np.testing.assert_allclose(_f(out["weights"]), [1.0], err_msg="one particle: its weight is 1")


@pytest.mark.grades("fastslam_step", points=4)
def test_fastslam_step_initializes_a_new_landmark_from_its_first_observation(lab):
    """A landmark seen for the first time.

    Its mean is h^-1(z, x), its covariance H^-1 Qt H^-T; the weight is unchanged.
    """
    poses = np.array([[0.0, 0.0, 0.0], [1.0, -1.0, 0.5], [-2.0, 3.0, -2.0]])
    state = _state(
        poses,
        np.zeros((3, 2, 2)),
        np.broadcast_to(10000 * np.eye(2), (3, 2, 2, 2)).copy(),
        np.zeros((3, 2), dtype=bool),
    )
    r, phi = 2.0, 0.3
    out = lab.fastslam_step(
        state,
        [0.0, 0.0],
        [[r, phi, 1.0]],
        np.zeros((3, 3)),
        QT,
        np.random.default_rng(8),
        dt=0.1,
        resample=False,
    )
    seen = np.asarray(out["seen"], dtype=bool)
    np.testing.assert_array_equal(
        seen,
        [[False, True]] * 3,
        err_msg="landmark 1 observed for the first time: seen becomes True in every particle, "
        "landmark 0 stays unseen",
    )
    expected = poses[:, :2] + r * np.stack(
        [np.cos(poses[:, 2] + phi), np.sin(poses[:, 2] + phi)], -1
    )
    np.testing.assert_allclose(
        _f(out["means"])[:, 1],
        expected,
        atol=1e-9,
        err_msg="the new landmark's mean is x + r (cos(theta + phi), sin(theta + phi)) in each "
        "particle",
    )
    for k in range(3):
        d = expected[k] - poses[k, :2]
        H = np.array([[d[0] / r, d[1] / r], [-d[1] / r**2, d[0] / r**2]])
        Hi = np.linalg.inv(H)
        np.testing.assert_allclose(
            _f(out["covs"])[k, 1],
            Hi @ QT @ Hi.T,
            rtol=1e-7,
            atol=1e-12,
            err_msg="the new landmark's covariance is H^-1 Qt H^-T",
        )
    np.testing.assert_allclose(
        _f(out["weights"]),
        np.full(3, 1 / 3),
        atol=1e-12,
        err_msg="a first observation weighs every particle by the same p0: weights stay 1/3",
    )
    # after a motion: the new landmark hangs off the PREDICTED pose
    u, dt = np.array([1.0, 0.5]), 0.2
    moved = poses + np.column_stack(
        [u[0] * dt * np.cos(poses[:, 2]), u[0] * dt * np.sin(poses[:, 2]), np.full(3, u[1] * dt)]
    )
    out = lab.fastslam_step(
        state,
        u,
        [[r, phi, 1.0]],
        np.zeros((3, 3)),
        QT,
        np.random.default_rng(8),
        dt=dt,
        resample=False,
    )
    expected = moved[:, :2] + r * np.stack(
        [np.cos(moved[:, 2] + phi), np.sin(moved[:, 2] + phi)], -1
    )
    np.testing.assert_allclose(
        _f(out["means"])[:, 1],
        expected,
        atol=1e-9,
        err_msg="v = 1 m/s, omega = 0.5 rad/s, dt = 0.2, Q = 0: the first observation is placed "
        "from "
        "the pose after the motion update",
    )


@pytest.mark.grades("fastslam_step", points=5)
def test_fastslam_step_weights_are_normalized_and_finite_for_far_off_landmarks(lab):
    # every particle's landmark is ~25 m from where it is measured with a 0.1 m belief:
    # each likelihood is about exp(-15000), which underflows to 0.0 in float64.
    """Every likelihood underflows (exp(-15000)).

    The weights still come out finite and normalized.
    """
    m = 6
    pose = np.array([0.0, 0.0, 0.0])
    offsets = np.array([0.0, 0.002, -0.001, 0.004, 0.0005, 0.003])
    means = np.zeros((m, 1, 2))
    means[:, 0, 0] = 30.0 + offsets
    covs = np.broadcast_to(0.01 * np.eye(2), (m, 1, 2, 2)).copy()
    state = _state(np.tile(pose, (m, 1)), means, covs, np.ones((m, 1), dtype=bool))
    z = np.array([[5.0, 0.0, 0.0]])
    out = lab.fastslam_step(
        state, [0.0, 0.0], z, np.zeros((3, 3)), QT, np.random.default_rng(9), dt=0.1, resample=False
    )
    w = _f(out["weights"])
    assert np.all(np.isfinite(w)), f"weights must stay finite, got {w}"
    np.testing.assert_allclose(w.sum(), 1.0, atol=1e-12, err_msg="weights must sum to 1")
    ll = np.array([_kalman(means[k, 0], covs[k, 0], z[0, :2], pose, QT)[2] for k in range(m)])
    assert ll.max() < -745, "the test needs likelihoods that underflow"
    expected = np.exp(ll - ll.max())
    np.testing.assert_allclose(
        w,
        expected / expected.sum(),
        rtol=1e-6,
        atol=1e-12,
        err_msg="weights = exp(log w - max log w) / sum, computed in log space",
    )


@pytest.mark.grades("fastslam_step", points=3)
def test_fastslam_step_multiplies_incoming_weights(lab):
    """Non-uniform weights in, resample=False: w_new ~ w_old N(z; z_hat, Q) per particle."""
    m = 5
    rng = np.random.default_rng(12)
    poses = np.column_stack([rng.normal(0, 0.2, (m, 2)), rng.normal(0.1, 0.05, m)])
    means = np.tile([[[4.0, 1.0]]], (m, 1, 1))
    covs = np.broadcast_to(0.05 * np.eye(2), (m, 1, 2, 2)).copy()
    w_old = np.array([0.5, 0.05, 0.2, 0.15, 0.1])
    state = _state(poses, means, covs, np.ones((m, 1), dtype=bool), w_old)
    z = np.array([[4.1, 0.15, 0.0]])
    out = lab.fastslam_step(
        state,
        [0.0, 0.0],
        z,
        np.zeros((3, 3)),
        QT,
        np.random.default_rng(13),
        dt=0.1,
        resample=False,
    )
    ll = np.array([_kalman(means[k, 0], covs[k, 0], z[0, :2], poses[k], QT)[2] for k in range(m)])
    expected = w_old * np.exp(ll - ll.max())
    np.testing.assert_allclose(
        _f(out["weights"]),
        expected / expected.sum(),
        rtol=1e-6,
        atol=1e-12,
        err_msg=f"incoming weights {w_old}: new weights = old weights * likelihood, normalized",
    )


@pytest.mark.grades("fastslam_step", points=2)
def test_fastslam_step_without_observations_keeps_weights_and_particles(lab):
    """No observation: nothing to weight, so no resampling: weights and particle order survive."""
    m = 4
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 2.0, -2.0], [3.0, 1.0, 3.0]])
    means = np.arange(m * 2 * 2, dtype=float).reshape(m, 2, 2)
    covs = np.broadcast_to(0.1 * np.eye(2), (m, 2, 2, 2)).copy()
    w_old = np.array([0.7, 0.1, 0.15, 0.05])
    state = _state(poses, means, covs, np.ones((m, 2), dtype=bool), w_old)
    u, dt = np.array([0.5, 0.2]), 0.1
    moved = np.column_stack(
        [
            poses[:, 0] + u[0] * dt * np.cos(poses[:, 2]),
            poses[:, 1] + u[0] * dt * np.sin(poses[:, 2]),
            _wrap(poses[:, 2] + u[1] * dt),
        ]
    )
    for observations in (np.empty((0, 3)), None):
        out = lab.fastslam_step(
            state, u, observations, np.zeros((3, 3)), QT, np.random.default_rng(14), dt=dt
        )
        what = "None" if observations is None else "an empty (0, 3) array"
        np.testing.assert_allclose(
            _f(out["weights"]),
            w_old,
            atol=1e-12,
            err_msg=f"observations = {what}: the weights must stay {w_old} (no resampling)",
        )
        np.testing.assert_allclose(
            _f(out["poses"]),
            moved,
            atol=1e-12,
            err_msg=f"observations = {what}: every particle moves, in its own order (no "
            f"resampling)",
        )
        np.testing.assert_allclose(
            _f(out["means"]), means, atol=0, err_msg=f"observations = {what}: landmarks unchanged"
        )


@pytest.mark.grades("fastslam_step", points=2)
def test_fastslam_step_resampling_keeps_each_particle_whole(lab):
    """Resampling with several survivors keeps each particle's pose, map and weight together.

    Five particles whose measurement fits equally well keep their incoming weights
    (0.1, 0.1, 0.2, 0.2, 0.4): low-variance resampling takes particle 4 twice, particles
    2 and 3 once and one of particles 0 and 1. Each new particle must be one of the
    updated particles whole (its pose with its own landmarks), and every weight 1/M.
    """
    m = 5
    shift = np.arange(m, dtype=float)  # particle k sits k m east of particle 0, its map too
    poses = np.column_stack([shift, np.zeros(m), np.full(m, 0.1)])
    means = np.stack([np.column_stack([shift + 4.0, np.ones(m)])], axis=1)  # (m, 1, 2)
    covs = np.broadcast_to(0.05 * np.eye(2), (m, 1, 2, 2)).copy()
    w_old = np.array([0.1, 0.1, 0.2, 0.2, 0.4])
    args = ([0.0, 0.0], [[4.1, 0.15, 0.0]], np.zeros((3, 3)), QT)

    def step(resample):
        state = _state(poses, means, covs, np.ones((m, 1), dtype=bool), w_old)
        out = lab.fastslam_step(state, *args, np.random.default_rng(14), dt=0.1, resample=resample)
        return {k: _f(out[k]) for k in ("poses", "means", "covs", "weights")}

    kept, drawn = step(False), step(True)
    np.testing.assert_allclose(
        kept["weights"],
        w_old,
        rtol=1e-9,
        err_msg="resample=False, the same likelihood for every particle: expected the incoming "
        "weights (0.1, 0.1, 0.2, 0.2, 0.4) back",
    )
    source = [int(np.argmin(np.abs(kept["poses"][:, 0] - x))) for x in drawn["poses"][:, 0]]
    for i, j in enumerate(source):
        for key in ("poses", "means", "covs"):
            np.testing.assert_allclose(
                drawn[key][i],
                kept[key][j],
                atol=1e-9,
                err_msg=f"resampled particle {i} has the pose of updated particle {j}: expected "
                f"its {key} to be particle {j}'s too (one index for the whole particle)",
            )
    counts = np.bincount(source, minlength=m)
    assert counts[2] == counts[3] == 1 and counts[4] == 2 and counts[0] + counts[1] == 1, (
        f"weights (0.1, 0.1, 0.2, 0.2, 0.4) over 5 particles: low-variance resampling takes "
        f"particle k floor(5 w_k) or ceil(5 w_k) times, so (0 or 1, 0 or 1, 1, 1, 2); got "
        f"{counts.tolist()}"
    )
    np.testing.assert_allclose(
        drawn["weights"],
        np.full(m, 1 / m),
        rtol=1e-12,
        err_msg="after resampling the cloud itself carries the weights: every weight is 1/M = 0.2",
    )


@pytest.mark.grades("fastslam_step", points=3)
def test_fastslam_step_resampling_copies_landmarks_without_aliasing(lab):
    # particle 0's landmark agrees with the measurement, the others are 2 m off:
    # resampling must pick particle 0 for every slot, as independent copies.
    """Resampling copies landmark arrays.

    No two particles share memory, the input state is untouched.
    """
    m = 6
    poses = np.zeros((m, 3))
    means = np.zeros((m, 2, 2))
    means[:, 0] = [[4.0, 0.0]] + np.array([[0.0, 0.0]] + [[0.0, 2.0]] * (m - 1))
    means[:, 1] = [-3.0, 1.0]
    covs = np.broadcast_to(0.01 * np.eye(2), (m, 2, 2, 2)).copy()
    state = _state(poses, means, covs, np.ones((m, 2), dtype=bool))
    before = {k: np.array(v, copy=True) for k, v in state.items()}
    out = lab.fastslam_step(
        state,
        [0.0, 0.0],
        [[4.0, 0.0, 0.0]],
        np.zeros((3, 3)),
        QT,
        np.random.default_rng(10),
        dt=0.1,
    )
    for k, v in before.items():  # the input state is not modified
        np.testing.assert_array_equal(
            np.asarray(state[k]), v, err_msg=f"fastslam_step modified state[{k!r}]"
        )
    out_means, out_covs = np.asarray(out["means"]), np.asarray(out["covs"])
    np.testing.assert_allclose(
        out_means[:, 0],
        np.tile([4.0, 0.0], (m, 1)),
        atol=1e-9,
        err_msg="every slot must hold the matching particle 0's landmark at (4, 0)",
    )
    np.testing.assert_allclose(
        _f(out["weights"]), np.full(m, 1 / m), err_msg="after resampling every weight is 1/M"
    )
    assert not np.shares_memory(out_means, state["means"]) and not np.shares_memory(
        out_covs, state["covs"]
    ), "the new state must not share memory with the input state"
    for i in range(m):
        for j in range(i + 1, m):
            assert not np.shares_memory(out_means[i], out_means[j]), (
                f"particles {i} and {j} share landmark means"
            )
            assert not np.shares_memory(out_covs[i], out_covs[j]), (
                f"particles {i} and {j} share landmark covariances"
            )
    out_means[0, 0] += 1.0
    out_covs[0, 0] *= 2.0
    np.testing.assert_allclose(
        out_means[1, 0],
        [4.0, 0.0],
        atol=1e-9,
        err_msg="changing the first particle's landmark must not move the second's",
    )
    assert out_covs[1, 0, 0, 0] < 0.01, (
        "doubling particle 0's covariance must not change particle 1's"
    )


# -- fastslam: 16 -----------------------------------------------------------------------

#: End-to-end bounds on robot seed 1 with 50 particles, median over three filter seeds.
#: The reference solution's median-of-3 stays below 0.23 m (landmarks) and 0.18 m (final
#: pose) over 30 filter seeds on robot seeds 0-2 (worst single run 0.43 m / 0.69 m); dead
#: reckoning ends 1 to 2 m off. Without the bearing wrap the errors are metres; with the
#: handout's weight formula the particles are not corrected and the final pose is > 1 m off.
LANDMARK_RMSE_BOUND = 0.40
FINAL_POSE_BOUND = 0.50
E2E_SEEDS = (0, 1, 2)


def _errors(run, landmarks, final_pose):
    lm_rmse = np.sqrt(np.mean(np.sum((np.asarray(landmarks, float) - run.fiducials) ** 2, 1)))
    return lm_rmse, np.hypot(*(np.asarray(final_pose, float)[:2] - run.true_poses[-1, :2]))


def _variant_fastslam(run, n_particles, rng, *, wrap=True, seed_weight=False):
    """A compact FastSLAM 1.0 (first-observation initialization) with two switchable bugs.

    ``wrap=False``: the seed's bearing ``atan2(...) - theta`` and error ``z - z_hat``
    without the wrap. ``seed_weight=True``: the handout's ``|2 pi Q|^(+1/2) exp(-e^T Q e / 2)``.
    Returns (landmark RMSE, final pose error).
    """
    m, k = n_particles, run.fiducials.shape[0]
    poses = np.tile(run.x0, (m, 1))
    mu, P, seen = np.zeros((m, k, 2)), np.zeros((m, k, 2, 2)), np.zeros(k, dtype=bool)
    L, Qt = np.linalg.cholesky(run.Q), run.Qt
    for t, (v, om) in enumerate(run.commands):
        th = poses[:, 2]
        poses = poses + np.column_stack(
            [v * run.dt * np.cos(th), v * run.dt * np.sin(th), np.full(m, om * run.dt)]
        )
        poses = poses + rng.standard_normal((m, 3)) @ L.T
        poses[:, 2] = _wrap(poses[:, 2])
        logw = np.zeros(m)
        obs = run.measurements[run.measurements[:, 0] == t]
        for _, r, b, j in obs:
            j = int(j)
            if not seen[j]:
                a = poses[:, 2] + b
                mu[:, j] = poses[:, :2] + r * np.column_stack([np.cos(a), np.sin(a)])
            d = mu[:, j] - poses[:, :2]
            q = np.sum(d * d, 1)
            H = np.stack(
                [
                    np.column_stack([d[:, 0], d[:, 1]]) / np.sqrt(q)[:, None],
                    np.column_stack([-d[:, 1], d[:, 0]]) / q[:, None],
                ],
                1,
            )
            if not seen[j]:
                Hi = np.linalg.inv(H)
                P[:, j] = Hi @ Qt @ np.swapaxes(Hi, 1, 2)
                continue
            e = np.column_stack([r - np.sqrt(q), b - (np.arctan2(d[:, 1], d[:, 0]) - poses[:, 2])])
            if wrap:
                e[:, 1] = _wrap(e[:, 1])
            S = H @ P[:, j] @ np.swapaxes(H, 1, 2) + Qt
            Si = np.linalg.inv(S)
            K = P[:, j] @ np.swapaxes(H, 1, 2) @ Si
            mu[:, j] = mu[:, j] + (K @ e[:, :, None])[:, :, 0]
            P[:, j] = (np.eye(2) - K @ H) @ P[:, j]
            sign, weight_matrix = (1.0, S) if seed_weight else (-1.0, Si)
            logw += sign * 0.5 * np.log(np.linalg.det(2 * np.pi * S)) - 0.5 * np.einsum(
                "mi,mij,mj->m", e, weight_matrix, e
            )
        seen[obs[:, 3].astype(int)] = True
        if len(obs):
            w = np.exp(logw - logw.max())
            idx = np.minimum(
                np.searchsorted(np.cumsum(w / w.sum()), rng.uniform(0, 1 / m) + np.arange(m) / m),
                m - 1,
            )
            poses, mu, P = poses[idx], mu[idx], P[idx]
    return _errors(run, mu.mean(0), poses.mean(0))


@pytest.fixture(scope="module")
def fiducial_run():
    return FiducialRobot(seed=1).to_run()


@pytest.mark.grades("fastslam", points=8)
@requires("test_fastslam_output_shapes_and_start", "test_fastslam_reports_the_particle_means")
def test_fastslam_maps_the_fiducials_and_tracks_the_robot(lab, fiducial_run, request):
    """Robot random seed 1, 50 particles.

    Landmark RMSE < 0.4 m and final pose error < 0.5 m (median of 3).
    """
    run = fiducial_run
    errs = []
    for seed in E2E_SEEDS:
        out = lab.fastslam(run, 50, np.random.default_rng(seed), init="first_observation")
        errs.append(_errors(run, out["landmarks"], _f(out["path"])[-1]))
    lm_rmse, pose_err = np.median(errs, axis=0)
    assert lm_rmse < LANDMARK_RMSE_BOUND, (
        f"landmark RMSE {lm_rmse:.2f} m (median of 3 runs), bound {LANDMARK_RMSE_BOUND} m"
    )
    assert pose_err < FINAL_POSE_BOUND, (
        f"final pose error {pose_err:.2f} m (median of 3 runs), bound {FINAL_POSE_BOUND} m"
    )
    # the bounds are not vacuous: an independent correct filter meets them, both broken
    # variants miss them (a check of this test itself: run on the reference solution only)
    if request.config.getoption("--notebook") is not None:
        return
    for kw, ok in (({}, True), ({"wrap": False}, False), ({"seed_weight": True}, False)):
        v = np.median(
            [_variant_fastslam(run, 50, np.random.default_rng(s), **kw) for s in E2E_SEEDS], axis=0
        )
        within = v[0] < LANDMARK_RMSE_BOUND and v[1] < FINAL_POSE_BOUND
        assert within == ok, f"test self-check: variant {kw or 'correct'} errors {v} vs bounds"


@pytest.mark.grades("fastslam", points=4)
def test_fastslam_reports_the_particle_means(lab, fiducial_run):
    """The path is the mean of the particles (circular mean heading); the map their weighted
    mixture.

    The run's heading crosses +-pi three times, where an arithmetic mean of
    headings near +pi and -pi would point backwards.
    """
    out = lab.fastslam(
        fiducial_run, 20, np.random.default_rng(21), init="first_observation", history=True
    )
    path, particles = _f(out["path"]), _f(out["particles"])
    assert particles.shape == (fiducial_run.n_steps + 1, 20, 3), (
        f"history=True: particles must be (T + 1, M, 3) = {(fiducial_run.n_steps + 1, 20, 3)}, "
        f"got {particles.shape}"
    )
    np.testing.assert_allclose(
        path[:, :2],
        particles[:, :, :2].mean(1),
        atol=1e-9,
        err_msg="path (x, y) at each step = mean of the particles (uniform weights after "
        "resampling)",
    )
    heading = np.arctan2(np.sin(particles[:, :, 2]).mean(1), np.cos(particles[:, :, 2]).mean(1))
    wrong = angle_error(path[:, 2], heading, atol=1e-9)
    assert wrong is None, (
        "path heading at each step (index = step) must be the circular mean of the particles' "
        "headings: " + wrong
    )
    state = out["state"]
    w, mu, sig = _f(state["weights"]), _f(state["means"]), _f(state["covs"])
    assert np.all(w >= 0) and abs(w.sum() - 1.0) < 1e-9, (
        f"the final state's weights must be a distribution (>= 0, summing to 1), got sum "
        f"{w.sum():.6g}"
    )
    lm = np.einsum("k,kjd->jd", w, mu)
    d = mu - lm
    lm_cov = np.einsum("k,kjab->jab", w, sig) + np.einsum("k,kja,kjb->jab", w, d, d)
    np.testing.assert_allclose(
        _f(out["landmarks"]),
        lm,
        atol=1e-9,
        err_msg="landmarks = weighted mean over the final particles of their landmark means",
    )
    np.testing.assert_allclose(
        _f(out["landmark_covs"]),
        lm_cov,
        atol=1e-9,
        err_msg="landmark_covs = weighted mixture covariance (mean of covariances + spread of "
        "means)",
    )


@pytest.mark.grades("fastslam", points=2)
def test_fastslam_reports_unobserved_landmarks_as_nan(lab, fiducial_run):
    """A landmark never observed has no estimate.

    NaN in landmarks and landmark_covs, observed False.
    """
    import dataclasses

    meas = fiducial_run.measurements
    run = dataclasses.replace(fiducial_run, measurements=meas[meas[:, 3] != 3])
    out = lab.fastslam(run, 10, np.random.default_rng(22), init="first_observation")
    lm, cov = _f(out["landmarks"]), _f(out["landmark_covs"])
    observed = np.asarray(out["observed"], dtype=bool)
    assert not observed[3] and observed[[0, 1, 2, 4]].all(), (
        f"landmark 3 removed from every measurement: observed must be [T, T, T, F, T], got "
        f"{observed}"
    )
    assert np.all(np.isnan(lm[3])) and np.all(np.isnan(cov[3])), (
        f"landmark 3 was never observed: expected NaN, got mean {lm[3]} and covariance "
        f"{cov[3].tolist()}"
    )
    assert np.all(np.isfinite(lm[[0, 1, 2, 4]])), "observed landmarks must have finite estimates"


@pytest.mark.grades("fastslam", points=2)
def test_fastslam_output_shapes_and_start(lab):
    """A 40-step run: path (41, 3) starting at x0, landmarks (5, 2), within 0.5 m of the truth."""
    run = FiducialRobot(seed=2, n_steps=40).to_run()
    out = lab.fastslam(run, 8, np.random.default_rng(11), init="first_observation")
    path = _f(out["path"])
    assert path.shape == (41, 3), "40 steps: the path has 41 rows (x0 first)"
    np.testing.assert_allclose(path[0], run.x0, atol=1e-12, err_msg="path[0] must be x0")
    assert _f(out["landmarks"]).shape == (5, 2), "5 fiducials: landmarks must have shape (5, 2)"
    seen_ids = np.unique(run.measurements[:, 3]).astype(int)
    assert np.all(np.isfinite(_f(out["landmarks"])[seen_ids])), (
        "every landmark that was observed must have a finite estimate"
    )
    # 4 s of driving: the estimate stays within half a metre of the truth at every step
    assert np.max(np.hypot(*(path[:, :2] - run.true_poses[:, :2]).T)) < 0.5, (
        "a 4 s run: the path must stay within 0.5 m of the true poses"
    )
