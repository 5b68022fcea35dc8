"""robolab.evaluation: SE(2) alignment, ATE / RPE, map-to-map metrics.

Oracles: known transforms (exact recovery without noise, and a brute-force grid
search with noise), analytic errors of constructed paths and maps.
"""

from __future__ import annotations

import numpy as np
import pytest

from robolab.evaluation import (
    absolute_trajectory_error,
    align_path,
    align_points,
    occupancy_iou,
    occupied_distances,
    relative_pose_error,
)
from robolab.geometry import angle_diff, compose, transform_points
from robolab.maps import UNKNOWN, OccupancyGrid


@pytest.mark.parametrize("seed", range(6))
def test_align_points_recovers_a_known_transform_exactly(seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-5, 5, (rng.integers(2, 40), 2))
    pose = np.array([rng.uniform(-10, 10), rng.uniform(-10, 10), rng.uniform(-np.pi, np.pi)])
    est = align_points(pts, transform_points(pts, pose))
    np.testing.assert_allclose(est[:2], pose[:2], atol=1e-9)
    assert abs(angle_diff(est[2], pose[2])) < 1e-9


def _cost(pose, p, q):
    return np.sum((transform_points(p, pose) - q) ** 2)


@pytest.mark.parametrize("seed", range(3))
def test_align_points_with_noise_is_the_least_squares_optimum(seed):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-3, 3, (25, 2))
    truth = np.array([1.0, -0.5, 0.8])
    q = transform_points(p, truth) + rng.normal(0, 0.05, p.shape)
    est = align_points(p, q)
    assert np.hypot(*(est[:2] - truth[:2])) < 0.05 and abs(angle_diff(est[2], truth[2])) < 0.03
    # no nearby pose does better (brute-force neighbourhood search)
    best = _cost(est, p, q)
    for d in rng.normal(0, [0.01, 0.01, 0.005], (200, 3)):
        assert _cost(est + d, p, q) >= best - 1e-12


def test_align_points_never_reflects_and_skips_nan_rows():
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [np.nan, np.nan]])
    mirrored = p * [1.0, -1.0]  # a reflection is not a rigid motion
    pose = align_points(p, mirrored)
    aligned = transform_points(p[:3], pose)
    r = np.array([[np.cos(pose[2]), -np.sin(pose[2])], [np.sin(pose[2]), np.cos(pose[2])]])
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert np.sum((aligned - mirrored[:3]) ** 2) > 0.1
    # weights: a zero weight removes a point
    q = transform_points(p[:3], [1.0, 2.0, 0.3])
    q_bad = q.copy()
    q_bad[2] += 10.0
    np.testing.assert_allclose(
        align_points(np.vstack([p[:3], p[2:3]]), np.vstack([q, q_bad[2:3]]), weights=[1, 1, 1, 0]),
        [1.0, 2.0, 0.3],
        atol=1e-9,
    )


@pytest.mark.parametrize(
    "src, dst, match",
    [
        ([[0, 0]], [[1, 1]], "two"),
        ([[1, 1], [1, 1]], [[0, 0], [2, 2]], "coincide"),
        ([[0, 0], [1, 1]], [[0, 0]], "same shape"),
        ([[0, 0], [np.inf, 1]], [[0, 0], [1, 1]], "inf"),
    ],
)
def test_align_points_refuses_what_has_no_answer(src, dst, match):
    with pytest.raises(ValueError, match=match):
        align_points(src, dst)


def _circle_path(n=60):
    t = np.linspace(0, 2 * np.pi, n)
    return np.column_stack([3 * np.cos(t), 3 * np.sin(t), t + np.pi / 2])


def test_ate_is_zero_for_a_moved_copy_and_the_offset_without_alignment():
    truth = _circle_path()
    moved = compose(np.array([2.0, -1.0, 0.7]), truth)
    ate = absolute_trajectory_error(moved, truth)
    assert ate["rmse"] < 1e-9 and ate["heading_errors"].max() < 1e-9
    aligned, pose = align_path(moved, truth)
    np.testing.assert_allclose(aligned[:, :2], truth[:, :2], atol=1e-9)
    # a constant shift of 0.3 m without alignment: every error is 0.3
    shifted = truth + [0.3, 0.0, 0.0]
    raw = absolute_trajectory_error(shifted, truth, align=False)
    np.testing.assert_allclose(raw["errors"], 0.3)
    assert raw["rmse"] == pytest.approx(0.3) and raw["median"] == pytest.approx(0.3)


def test_rpe_sees_drift_that_ate_after_alignment_hides_partly():
    truth = np.column_stack([np.linspace(0, 10, 101), np.zeros(101), np.zeros(101)])
    # odometry that overestimates every step by 2 %: each 0.1 m step is 0.102 m
    est = truth * [1.02, 1.0, 1.0]
    rpe = relative_pose_error(est, truth, delta=1)
    np.testing.assert_allclose(rpe["translation"], 0.002, atol=1e-12)
    assert rpe["rotation_rmse"] == 0.0
    rpe10 = relative_pose_error(est, truth, delta=10)
    np.testing.assert_allclose(rpe10["translation"], 0.02, atol=1e-12)
    # RPE does not depend on the estimate's frame
    moved = compose(np.array([5.0, 5.0, 1.0]), est)
    np.testing.assert_allclose(
        relative_pose_error(moved, truth)["translation"], rpe["translation"], atol=1e-9
    )
    with pytest.raises(ValueError, match="delta"):
        relative_pose_error(est, truth, delta=101)


def _room(res=0.05, shift=0.0, size=4.0):
    n = int(round(size / res))
    data = np.zeros((n, n))
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 1.0
    data[n // 2 :, n // 2] = 1.0
    data[1:3, 1:3] = UNKNOWN  # unknown plays no part
    return OccupancyGrid(data, res, np.array([shift, 0.0, 0.0]))


def test_occupied_distances_measure_a_shifted_map():
    ref = _room()
    assert occupied_distances(ref, ref).max() == 0.0
    moved = _room(shift=0.15)  # three cells
    d = occupied_distances(moved, ref)
    # the walls parallel to the shift lie on the reference's; the others 0.15 m away,
    # except the right outer wall which lies 0.15 m beyond the reference
    assert np.mean(d < 1e-9) > 0.3  # the walls along the shift still coincide
    assert d.max() == pytest.approx(0.15, abs=1e-9)
    # moving it back with a transform removes the error
    assert occupied_distances(moved, ref, transform=[-0.15, 0.0, 0.0]).max() < 1e-9
    # another resolution: at most half a cell of each grid from the reference walls
    fine = _room(res=0.025)
    assert occupied_distances(fine, ref).max() <= 0.5 * (0.05 + 0.025) * np.sqrt(2) + 1e-9
    with pytest.raises(ValueError, match="no occupied"):
        occupied_distances(ref, ref.with_data(np.zeros(ref.shape)))


def test_occupancy_iou_exact_and_within_a_tolerance():
    ref = _room()
    assert occupancy_iou(ref, ref) == 1.0
    moved = _room(shift=0.05)  # one cell
    a, b = (
        moved.cell_to_world(np.argwhere(moved.occupied)),
        ref.cell_to_world(np.argwhere(ref.occupied)),
    )
    ka = {tuple(np.round(p, 6)) for p in a}
    kb = {tuple(np.round(p, 6)) for p in b}
    exact = len(ka & kb) / len(ka | kb)  # brute-force set IoU
    assert occupancy_iou(moved, ref) == pytest.approx(exact)
    assert exact < 0.8
    assert occupancy_iou(moved, ref, tolerance=0.05) == 1.0
    empty = ref.with_data(np.zeros(ref.shape))
    assert occupancy_iou(empty, ref) == 0.0 and occupancy_iou(empty, empty) == 1.0
    with pytest.raises(ValueError, match="tolerance"):
        occupancy_iou(ref, ref, tolerance=-1.0)
