"""Visible checks for lab 05, Monte Carlo localization (``notebooks/05_mcl.ipynb``).

Quick and friendly: shapes, a worked example, one invariant each. The hidden
tests check much more (Table 5.6 moments, brute-force distance fields, the
Table 6.3 oracle, tracking and global localization on the bag).
"""

from __future__ import annotations

import math

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_raises, expect_shape
from robolab.maps import UNKNOWN, OccupancyGrid

__all__ = [
    "check_init_uniform",
    "check_init_gaussian",
    "check_sample_motion_model_odometry",
    "check_likelihood_field",
    "check_likelihood_field_model",
    "check_normalize_log_weights",
    "check_low_variance_resample",
    "check_mcl_step",
    "check_kld_sample_size",
    "check_augmented_mcl_step",
]


def _box() -> OccupancyGrid:
    """A 2 m x 1.5 m room at 10 cm: a wall ring, one pillar, unknown outside."""
    data = np.full((19, 24), UNKNOWN)
    data[1:18, 1:23] = 1.0
    data[2:17, 2:22] = 0.0
    data[8:11, 14:17] = 1.0
    return OccupancyGrid(data, 0.1, (-0.5, -0.3, 0.0))


def _field(grid, sigma=0.1, max_dist=0.5):
    from scipy import ndimage

    d = np.minimum(ndimage.distance_transform_edt(~grid.occupied) * grid.resolution, max_dist)
    return {
        "distance": d,
        "likelihood": np.exp(-0.5 * (d / sigma) ** 2) / (math.sqrt(2 * math.pi) * sigma),
        "resolution": grid.resolution,
        "origin": grid.origin.copy(),
        "sigma_hit": sigma,
        "max_dist": max_dist,
    }


def _scan_at(grid, pose, n=36, range_max=4.0):
    from robolab.raycast import cast_rays

    angles = np.linspace(-np.pi, np.pi, n, endpoint=False)
    return {
        "ranges": cast_rays(grid, np.asarray(pose, float)[None], angles, range_max)[0],
        "angles": angles,
        "range_min": 0.05,
        "range_max": range_max,
    }


@check
def check_init_uniform(init_uniform):
    """Every particle in a free cell, headings in [-pi, pi), not all at cell centres."""
    grid = _box()
    p = expect_shape(
        "init_uniform(grid, 2000, rng)",
        init_uniform(grid, 2000, np.random.default_rng(0)),
        (2000, 3),
    )
    rc = grid.world_to_cell(p[:, :2])
    if not (np.all(grid.contains_cell(rc)) and np.all(grid.free[rc[:, 0], rc[:, 1]])):
        raise CheckFailed(
            "some particles are outside the free space: draw cells among grid.free only"
        )
    if np.any(p[:, 2] < -np.pi) or np.any(p[:, 2] >= np.pi):
        raise CheckFailed("headings must be in [-pi, pi)")
    frac = grid.world_to_map(p[:, :2]) % 1.0
    if np.allclose(frac, 0.5):
        raise CheckFailed("all particles sit at cell centres: add a uniform offset inside the cell")


@check
def check_init_gaussian(init_gaussian):
    """Mean and spread of 20 000 samples; zero covariance gives copies of the pose."""
    p = expect_shape(
        "init_gaussian",
        init_gaussian(
            [1.0, 2.0, 0.5], np.diag([0.04, 0.01, 0.0025]), 20000, np.random.default_rng(1)
        ),
        (20000, 3),
    )
    expect_close("sample mean", p.mean(axis=0), [1.0, 2.0, 0.5], atol=0.01)
    expect_close("sample standard deviations", p.std(axis=0), [0.2, 0.1, 0.05], atol=0.01)
    expect_close(
        "init_gaussian with cov = 0",
        init_gaussian([1.0, 2.0, 0.5], np.zeros((3, 3)), 3, np.random.default_rng(2)),
        np.tile([1.0, 2.0, 0.5], (3, 1)),
    )


@check
def check_sample_motion_model_odometry(sample_motion_model_odometry):
    """Noise-free, a particle moves as the odometry did, in its own frame; noise spreads it."""
    p = np.array([[0.0, 0.0, np.pi / 2], [1.0, 1.0, 0.0]])
    moved = sample_motion_model_odometry(
        p, [0.0, 0.0, 0.0], [1.0, 0.0, 0.5], (0, 0, 0, 0), np.random.default_rng(3)
    )
    moved = expect_shape("sample_motion_model_odometry(particles (2, 3), ...)", moved, (2, 3))
    expect_close(
        "noise-free motion of 1 m forward then a 0.5 rad turn",
        moved,
        [[0.0, 1.0, np.pi / 2 + 0.5], [2.0, 1.0, 0.5]],
        atol=1e-9,
    )
    cloud = sample_motion_model_odometry(
        np.zeros((20000, 3)),
        [0, 0, 0],
        [1.0, 0.0, 0.0],
        (0.0, 0.0, 0.04, 0.0),
        np.random.default_rng(4),
    )
    std = float(np.asarray(cloud, float)[:, 0].std())
    if abs(std - 0.2) > 0.01:
        raise CheckFailed(
            f"with alpha3 = 0.04 and trans = 1 m the translation variance is alpha3 trans^2 = 0.04 "
            f"(std 0.2 m); your std is {std:.3f} m. "
            "Table 5.6 uses variances, not standard deviations"
        )


@check
def check_likelihood_field(likelihood_field):
    """Distances in metres on a small room, clipped at max_dist."""
    grid = _box()
    field = likelihood_field(grid, 0.1, 0.5)
    if not isinstance(field, dict) or "distance" not in field:
        raise CheckFailed(
            "return a dict with at least 'distance', 'likelihood', 'resolution', 'origin', "
            "'sigma_hit', 'max_dist'"
        )
    d = expect_shape("field['distance']", field["distance"], grid.shape)
    if d[grid.occupied].max() != 0:
        raise CheckFailed("occupied cells must have distance 0")
    expect_close("distance of the cell next to a wall (one cell = 0.1 m)", d[2, 5], 0.1)
    expect_close("largest distance (clipped at max_dist)", d.max(), 0.5)
    expect_close("field['resolution']", field["resolution"], 0.1)


@check
def check_likelihood_field_model(likelihood_field_model):
    """The true pose scores higher than a pose 20 cm off; shape (N,)."""
    grid = _box()
    truth = np.array([0.4, 0.5, 0.3])
    scan = _scan_at(grid, truth)
    particles = np.array([truth, truth + [0.2, 0.0, 0.0], truth + [0.0, 0.0, 0.3]])
    logw = expect_shape(
        "likelihood_field_model(scan, particles (3, 3), ...)",
        likelihood_field_model(scan, particles, _field(grid), {"z_hit": 0.9, "z_rand": 0.1}),
        (3,),
    )
    if not np.all(np.isfinite(logw)):
        raise CheckFailed("log-weights must be finite")
    if not (logw[0] > logw[1] and logw[0] > logw[2]):
        raise CheckFailed(f"the true pose should score best, got log-weights {logw}")


@check
def check_normalize_log_weights(normalize_log_weights):
    """Log-weights around -1000 must not underflow."""
    w = expect_shape(
        "normalize_log_weights",
        normalize_log_weights(np.array([-1000.0, -1000.0 + math.log(3)])),
        (2,),
    )
    expect_close("normalize_log_weights([-1000, -1000 + log 3])", w, [0.25, 0.75])
    expect_raises(
        "normalize_log_weights when every log-weight is -inf (every weight vanished)",
        ValueError,
        normalize_log_weights,
        np.full(3, -np.inf),
    )


@check
def check_low_variance_resample(low_variance_resample):
    """Equal weights keep every particle once; weight 0 is never drawn."""
    p = np.arange(12.0).reshape(4, 3)
    out = expect_shape(
        "low_variance_resample",
        low_variance_resample(p, np.full(4, 0.25), np.random.default_rng(5)),
        (4, 3),
    )
    expect_close(
        "equal weights: every particle exactly once (sorted rows)", np.sort(out[:, 0]), p[:, 0]
    )
    out = np.asarray(
        low_variance_resample(p, [0.0, 0.5, 0.5, 0.0], np.random.default_rng(6)), float
    )
    if set(out[:, 0]) != {3.0, 6.0}:
        raise CheckFailed("particles of weight 0 must never be drawn")


@check
def check_mcl_step(mcl_step):
    """A filter at the true pose stays there; a motion below the thresholds does nothing."""
    grid = _box()
    truth = np.array([0.4, 0.5, 0.3])
    rng = np.random.default_rng(7)
    p = truth + rng.normal(0, [0.1, 0.1, 0.1], (300, 3))
    w = np.full(300, 1 / 300)
    out = mcl_step(
        p,
        w,
        [0, 0, 0],
        [0, 0, 0],
        _scan_at(grid, truth),
        _field(grid),
        {"alphas": (0.01,) * 4, "force_update": True},
        rng,
    )
    if len(out) != 3:
        raise CheckFailed("return (particles, weights, updated)")
    p2, w2 = expect_shape("particles", out[0], (300, 3)), expect_shape("weights", out[1], (300,))
    expect_close("sum of the weights", w2.sum(), 1.0)
    mean = np.average(p2[:, :2], axis=0, weights=w2)
    if np.hypot(*(mean - truth[:2])) > 0.05:
        raise CheckFailed(
            f"after one update the mean should be near the true position {truth[:2]}, got {mean}"
        )
    w_in = np.linspace(1.0, 2.0, 300) / np.linspace(1.0, 2.0, 300).sum()
    out = mcl_step(
        p,
        w_in,
        [0, 0, 0],
        [0.01, 0, 0],
        _scan_at(grid, truth),
        _field(grid),
        {"update_min_d": 0.2, "update_min_a": 0.5},
        rng,
    )
    if bool(out[2]):
        raise CheckFailed("a 1 cm motion is below update_min_d = 0.2 m: the filter must not update")
    expect_close("weights returned without an update (the incoming ones)", out[1], w_in)


@check
def check_kld_sample_size(kld_sample_size):
    """Table 8.4 for k = 2 and k = 100 bins."""
    expect_close("kld_sample_size(2, 0.05, 2.326)", kld_sample_size(2, 0.05, 2.326), 66)
    b = 2 / (9 * 99)
    expect_close(
        "kld_sample_size(100, 0.05, 2.326)",
        kld_sample_size(100, 0.05, 2.326),
        math.ceil(99 / 0.1 * (1 - b + math.sqrt(b) * 2.326) ** 3),
    )
    expect_close(
        "kld_sample_size(1, 0.05, 2.326): one bin needs one sample",
        kld_sample_size(1, 0.05, 2.326),
        1,
    )


@check
def check_augmented_mcl_step(augmented_mcl_step):
    """Starting from w_slow = w_fast = 0 both become w_avg, so nothing is replaced."""
    grid = _box()
    truth = np.array([0.4, 0.5, 0.3])
    p = truth + np.random.default_rng(8).normal(0, 0.03, (200, 3))
    out = augmented_mcl_step(
        p,
        np.full(200, 1 / 200),
        [0, 0, 0],
        [0, 0, 0],
        _scan_at(grid, truth),
        _field(grid),
        {"alphas": (0.01,) * 4},
        np.random.default_rng(9),
        grid,
        0.0,
        0.0,
    )
    if len(out) != 4:
        raise CheckFailed("return (particles, weights, w_slow, w_fast)")
    p2 = expect_shape("particles", out[0], (200, 3))
    if not float(out[2]) > 0 or not math.isclose(float(out[2]), float(out[3])):
        raise CheckFailed(
            f"from 0, w_slow and w_fast should both start at w_avg > 0, got {out[2]}, {out[3]}"
        )
    if np.hypot(*(p2[:, :2] - truth[:2]).T).max() > 0.5:
        raise CheckFailed("no random particle should be injected while the filter tracks well")
