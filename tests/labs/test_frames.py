"""Hidden tests for lab 00, bags and frames (seed 000, task 1). 100 points.

Every test calls only ``lab.<exercise>(...)`` with plain data and compares
results after ``np.asarray(..., dtype=float)``, so it runs on the reference
solution and, with ``--notebook``, across the grader's process boundary.

Oracles: hand-computed cases (in the comments), the library's
``robolab.geometry.transform_points`` and ``compose``, ``robolab.bag.Scans.endpoints``
and ``robolab.bag.PoseTrack.at``. End to end: the first 2 s of the bundled
``data/localization.bag`` (the robot inside an office, walls all around), whose
scans, placed with odometry and the laser mount, must land on the walls of
``data/office.yaml``.

Points: scan_to_cartesian 30, transform_points 35, pose_at 35. Refusal and
end-to-end tests pay only when the exercise's value tests pass (``requires``).

A reading is a real return when it is finite, positive and within
``[range_min, range_max)``: a reading of exactly ``range_max`` is a max-range
reading (docs/architecture.md, "Lab decisions"), and the notebook says so.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy import ndimage

from robolab import DATA_DIR
from robolab.bag import BagReader, PoseTrack, Scans, laser_pose_in_base
from robolab.checks.base import angle_error
from robolab.geometry import angle_diff, compose
from robolab.geometry import transform_points as oracle_transform
from robolab.maps import load_map

grades = pytest.mark.grades

#: CPU seconds the reference solution's worker uses while graded (loading and every call,
#: children included: `cpu_seconds` of the correct example in `make grade`'s gradebook.json,
#: 2026-12-02): a submission gets 8 times that in total, at least 20 s (docs/grading.md).
REFERENCE_CPU_SECONDS = 0.2

# The functions take microseconds; a hanging submission should not cost a minute per test.
GRADING_LIMITS = {"cpu_seconds": 10.0, "wall_seconds": 20.0}

#: Seconds of the bag used end to end: the odometry has not drifted yet (README: within
#: a few centimetres over the first 2 s).
BAG_SECONDS = 2.0
#: Bound on the median distance (m) of correctly placed endpoints to the nearest wall
#: surface. The hit noise is N(0, 0.02^2), whose |.| has median 0.675 * 0.02 = 0.0135 m;
#: placed with the ground truth the median is 0.013 m, with 2 s of odometry 0.016 m.
#: 0.025 m leaves room for interpolation and float32 rounding, not for a wrong transform
#: (forgetting the 0.1 m laser mount gives 0.052 m; a sign error in the rotation, metres).
WALL_MEDIAN_BOUND = 0.025


def _f(x):
    return np.asarray(x, dtype=float)


# ---------------------------------------------------------------------------- bag fixtures
@lru_cache(maxsize=1)
def _bag():
    """The first BAG_SECONDS of localization.bag, read with the library, as plain arrays."""
    with BagReader(DATA_DIR / "localization.bag") as bag:
        bag.preload(["/base_scan", "/odom", "/ground_truth", "/tf"])
        scans = bag.scans("/base_scan")
        odom = bag.odometry("/odom")
        truth = bag.odometry("/ground_truth")
        mount = laser_pose_in_base(bag.tf(), scans.frame_id)
    first = scans.stamps - scans.stamps[0] <= BAG_SECONDS
    keep_odom = odom.stamps <= scans.stamps[first][-1] + 0.5
    return {
        "scans": Scans(
            scans.stamps[first],
            scans.ranges[first],
            scans.angles,
            scans.range_min,
            scans.range_max,
            scans.frame_id,
        ),
        "odom_stamps": odom.stamps[keep_odom],
        "odom_poses": odom.poses[keep_odom],
        "map_from_odom": truth.poses[0],  # README: odom starts at the first ground-truth pose
        "mount": mount,
    }


@lru_cache(maxsize=1)
def _office():
    """The office map and, per cell, the nearest cell on the other side of a wall surface."""
    grid = load_map(DATA_DIR / "office.yaml")
    occ = grid.occupied
    _, to_occupied = ndimage.distance_transform_edt(~occ, return_indices=True)
    _, to_free = ndimage.distance_transform_edt(occ, return_indices=True)
    nearest = np.where(occ[None], to_free, to_occupied)  # (2, rows, cols)
    return grid, nearest


def _wall_distance(points):
    """Distance (m) from each point to the nearest wall surface of the office map.

    A point in a free cell: distance to the square of the nearest occupied cell; a point
    inside a wall: distance to the square of the nearest free cell. So a point displaced
    into a wall counts as much as one displaced away from it.
    """
    grid, nearest = _office()
    pts = _f(points)
    assert pts.ndim == 2 and pts.shape[1] == 2, (
        f"expected the endpoints as an array of shape (P, 2), got shape {pts.shape}"
    )
    assert np.all(np.isfinite(pts)), (
        f"expected finite endpoints only, got {int(np.sum(~np.isfinite(pts).all(axis=1)))} "
        "points with inf or NaN: invalid ranges must be dropped, not turned into points"
    )
    rc = grid.world_to_cell(pts)
    inside = grid.contains_cell(rc)
    r, c = rc[inside, 0], rc[inside, 1]
    centre = grid.cell_to_world(nearest[:, r, c].T)
    gap = np.maximum(np.abs(pts[inside] - centre) - grid.resolution / 2, 0.0)
    # Off the map (max-range readings of 8 m reach past the building): infinitely far.
    distance = np.full(len(pts), np.inf)
    distance[inside] = np.hypot(gap[:, 0], gap[:, 1])
    return distance


def _laser_poses_in_map(odom_poses, mount):
    """compose(map_from_odom, odom -> base_link, base_link -> laser) for every scan."""
    bag = _bag()
    return compose(compose(bag["map_from_odom"], odom_poses), mount)


# ============================================================== scan_to_cartesian (30)
@grades("scan_to_cartesian", points=5)
def test_scan_to_cartesian_hand_computed(lab):
    """scan_to_cartesian: beams at 0, 90, 180, -90, 45 and 150 degrees end at (r cos a, r sin a)."""
    ranges = [2.0, 1.0, 3.0, 0.5]
    angles = [0.0, np.pi / 2, np.pi, -np.pi / 2]
    out = _f(lab.scan_to_cartesian(ranges, angles, 0.1, 10.0))
    assert out.shape == (4, 2), (
        f"ranges [2, 1, 3, 0.5] at 0, 90, 180, -90 degrees, all valid: expected shape (4, 2), "
        f"got {out.shape}"
    )
    np.testing.assert_allclose(
        out,
        [[2.0, 0.0], [0.0, 1.0], [-3.0, 0.0], [0.0, -0.5]],
        atol=1e-12,
        err_msg="ranges [2, 1, 3, 0.5] at 0, 90, 180, -90 degrees: expected endpoints "
        "(2, 0), (0, 1), (-3, 0), (0, -0.5), i.e. (r cos a, r sin a)",
    )
    out = _f(
        lab.scan_to_cartesian(np.array([np.sqrt(2.0), 2.0]), np.radians([45.0, 150.0]), 0.0, 5.0)
    )
    np.testing.assert_allclose(
        out,
        [[1.0, 1.0], [-np.sqrt(3.0), 1.0]],
        atol=1e-12,
        err_msg="sqrt(2) m at 45 degrees and 2 m at 150 degrees: expected (1, 1) and (-sqrt(3), 1)",
    )


@grades("scan_to_cartesian", points=6)
def test_scan_to_cartesian_matches_library_on_random_scans(lab):
    """scan_to_cartesian: random scans with inf, NaN and 0 readings give the library's endpoints."""
    rng = np.random.default_rng(0)
    for b in (1, 7, 360, 1081):
        angles = np.sort(rng.uniform(-np.pi, np.pi, b))
        ranges = rng.uniform(0.0, 12.0, b)
        ranges[rng.random(b) < 0.1] = np.inf
        ranges[rng.random(b) < 0.05] = np.nan
        ranges[rng.random(b) < 0.05] = 0.0
        expected = Scans([0.0], ranges[None], angles, 0.2, 10.0, "laser").endpoints(0)
        out = _f(lab.scan_to_cartesian(ranges, angles, 0.2, 10.0))
        assert out.shape == expected.shape, (
            f"a random scan of {b} beams (range_min 0.2, range_max 10): expected "
            f"{expected.shape[0]} valid beams, shape {expected.shape}, got {out.shape}"
        )
        np.testing.assert_allclose(
            out,
            expected,
            atol=1e-12,
            err_msg=f"a random scan of {b} beams: expected the endpoints of the valid beams, "
            "in beam order",
        )


@grades("scan_to_cartesian", points=6)
def test_scan_to_cartesian_drops_every_kind_of_invalid_return(lab):
    """scan_to_cartesian: 0, inf, NaN, -inf, too short and too long readings are all dropped."""
    # Only beams 1 (1.0 m at 90 deg) and 5 (4.0 m at 0 deg) are real returns; the rest are
    # 0, +inf, NaN, below range_min (0.05), above range_max (8.0) and -inf.
    ranges = [0.0, 1.0, np.inf, np.nan, 0.04, 4.0, 8.5, -np.inf]
    angles = [0.1, np.pi / 2, 0.3, 0.4, 0.5, 0.0, 0.7, 0.8]
    out = _f(lab.scan_to_cartesian(ranges, angles, 0.05, 8.0))
    assert out.shape == (2, 2), (
        f"ranges {ranges} with range_min 0.05, range_max 8: expected the 2 valid beams only, "
        f"got {out.shape[0]} points: 0, inf, NaN and out-of-range readings mean 'no return'"
    )
    np.testing.assert_allclose(
        out,
        [[0.0, 1.0], [4.0, 0.0]],
        atol=1e-12,
        err_msg="the valid beams, 1.0 m at 90 and 4.0 m at 0 degrees: expected (0, 1), (4, 0)",
    )
    rng = np.random.default_rng(1)
    ranges = rng.choice([0.0, np.inf, np.nan, 0.01, 9.0, 2.5, 7.9, 0.06], size=500)
    out = _f(lab.scan_to_cartesian(ranges, np.linspace(-np.pi, np.pi, 500), 0.05, 8.0))
    valid = np.isin(ranges, [2.5, 7.9, 0.06])
    assert out.shape == (valid.sum(), 2), (
        f"500 beams mixing 0, inf, NaN, 0.01, 9.0 (invalid) and 2.5, 7.9, 0.06 (valid): expected "
        f"{valid.sum()} points, got shape {out.shape}"
    )
    np.testing.assert_allclose(
        np.hypot(out[:, 0], out[:, 1]),
        ranges[valid],
        rtol=1e-12,
        err_msg="500 mixed beams: expected each point's distance from the laser to be its range",
    )


@grades("scan_to_cartesian", points=6)
def test_scan_to_cartesian_at_the_bounds_of_the_valid_interval(lab):
    """scan_to_cartesian: range_min itself is a return; range_max itself and 0 are not."""
    # [range_min, range_max): 0.05 (= range_min) is kept; 8.0 (= range_max) is a max-range
    # reading, a failed return (the beam model's p_max), so it is dropped.
    out = _f(lab.scan_to_cartesian([0.05, 8.0, 3.0], [0.0, 0.0, np.pi / 2], 0.05, 8.0))
    assert out.shape == (2, 2), (
        f"ranges [0.05, 8.0, 3.0] with range_min 0.05, range_max 8.0: expected 2 returns "
        f"(a reading equal to range_min is valid; one equal to range_max is a max-range "
        f"reading, no return), got {out.shape[0]} points"
    )
    np.testing.assert_allclose(
        out,
        [[0.05, 0.0], [0.0, 3.0]],
        atol=1e-12,
        err_msg="ranges [0.05, 8.0, 3.0] at 0, 0, 90 degrees: expected (0.05, 0) and (0, 3)",
    )
    # With range_min = 0 a reading of 0 is still no return (a driver's "nothing measured").
    out = _f(lab.scan_to_cartesian([0.0, 1.0], [0.0, 0.0], 0.0, 8.0))
    assert out.shape == (1, 2), (
        f"ranges [0, 1] with range_min 0: expected 1 return (a reading of 0 is never a "
        f"return, even when range_min is 0), got {out.shape[0]} points"
    )


@grades("scan_to_cartesian", points=3)
def test_scan_to_cartesian_no_valid_beam_gives_empty_points(lab):
    """scan_to_cartesian: no valid beam gives an empty (0, 2) array; one beam gives one point.

    The smallest scans: nothing to return must not be an error, and a scan of a single
    beam is still a (1, 2) array of that beam's endpoint.
    """
    out = _f(lab.scan_to_cartesian([np.inf, 0.0, np.nan, 20.0], [0.0, 0.1, 0.2, 0.3], 0.1, 10.0))
    assert out.shape == (0, 2), (
        f"ranges [inf, 0, nan, 20] with range_max 10: no valid beam, expected shape (0, 2), "
        f"got {out.shape}"
    )
    one = _f(lab.scan_to_cartesian([2.0], [np.pi / 2], 0.1, 10.0))
    np.testing.assert_allclose(
        one,
        [[0.0, 2.0]],
        atol=1e-12,
        err_msg="a scan of one beam, 2 m at pi/2: expected one endpoint [[0, 2]] of shape (1, 2)",
    )
    one = _f(lab.scan_to_cartesian([3.0, np.inf], [0.0, 0.5], 0.1, 10.0))
    np.testing.assert_allclose(
        one,
        [[3.0, 0.0]],
        atol=1e-12,
        err_msg="ranges [3, inf] at angles [0, 0.5]: one valid beam, expected [[3, 0]]",
    )


SCAN_VALUES = (
    "test_scan_to_cartesian_hand_computed",
    "test_scan_to_cartesian_matches_library_on_random_scans",
)


@grades("scan_to_cartesian", points=2)
@pytest.mark.requires(*SCAN_VALUES)
def test_scan_to_cartesian_rejects_bad_input(lab, refuses):
    """scan_to_cartesian: a missing angle, range_min > range_max or a 2-D scan raise ValueError."""
    with refuses(ValueError, "3 ranges for 2 angles (one angle per range)"):
        lab.scan_to_cartesian([1.0, 2.0, 3.0], [0.0, 0.1], 0.1, 10.0)
    with refuses(ValueError, "range_min = 5 above range_max = 1"):
        lab.scan_to_cartesian([1.0, 2.0], [0.0, 0.1], 5.0, 1.0)
    with refuses(ValueError, "ranges and angles of shape (2, 3): one scan is one-dimensional (B,)"):
        lab.scan_to_cartesian(np.ones((2, 3)), np.zeros((2, 3)), 0.1, 10.0)


@grades("scan_to_cartesian", points=2)
@pytest.mark.requires(*SCAN_VALUES)
def test_scan_to_cartesian_on_the_bundled_bag(lab):
    """scan_to_cartesian: the bag's first 2 s of scans, placed with odometry, land on the walls."""
    bag = _bag()
    scans = bag["scans"]
    odom = PoseTrack(bag["odom_stamps"], bag["odom_poses"]).at(scans.stamps)
    laser = _laser_poses_in_map(odom, bag["mount"])
    cloud = []
    for k in range(len(scans)):
        pts = _f(
            lab.scan_to_cartesian(scans.ranges[k], scans.angles, scans.range_min, scans.range_max)
        )
        valid = int(scans.valid[k].sum())
        assert pts.ndim == 2 and pts.shape[1] == 2 and pts.shape[0] == valid, (
            f"bag scan {k}: expected {valid} valid beams (finite, within [range_min, "
            f"range_max)), got shape {pts.shape}"
        )
        cloud.append(oracle_transform(pts, laser[k]))
    median = np.median(_wall_distance(np.concatenate(cloud)))
    assert median < WALL_MEDIAN_BOUND, (
        f"the bag's endpoints placed at the odometry poses: expected a median distance to the "
        f"walls below {WALL_MEDIAN_BOUND} m, got {median:.3f} m"
    )


# =============================================================== transform_points (35)
@grades("transform_points", points=8)
def test_transform_points_hand_computed(lab):
    """transform_points: a frame at (1, 2) turned 90 degrees; a laser on a robot facing west."""
    # Child at (1, 2) turned 90 degrees: its x axis is the parent's y axis.
    out = _f(lab.transform_points([[1.0, 0.0], [0.0, 1.0], [2.0, -1.0]], [1.0, 2.0, np.pi / 2]))
    assert out.shape == (3, 2), f"3 points and one pose: expected shape (3, 2), got {out.shape}"
    np.testing.assert_allclose(
        out,
        [[1.0, 3.0], [0.0, 2.0], [2.0, 4.0]],
        atol=1e-12,
        err_msg="points (1, 0), (0, 1), (2, -1) of a frame at (1, 2, 90 deg): expected (1, 3), "
        "(0, 2), (2, 4) (rotate by R(theta) = [[cos, -sin], [sin, cos]], then translate)",
    )
    out = _f(lab.transform_points(np.array([[1.0, 0.0]]), np.array([4.9, 5.0, np.pi])))
    np.testing.assert_allclose(
        out,
        [[3.9, 5.0]],
        atol=1e-12,
        err_msg="point (1, 0) of a frame at (4.9, 5, pi): expected (3.9, 5), 1 m ahead facing west",
    )


@grades("transform_points", points=8)
def test_transform_points_matches_library_on_random_input(lab):
    """transform_points: random points and poses (any heading) give R(theta) p + t."""
    rng = np.random.default_rng(2)
    for p in (1, 5, 400):
        points = rng.normal(0.0, 4.0, (p, 2))
        pose = np.array([rng.uniform(-10, 10), rng.uniform(-10, 10), rng.uniform(-np.pi, np.pi)])
        out = _f(lab.transform_points(points.copy(), pose.copy()))
        assert out.shape == (p, 2), f"{p} points and one pose: expected ({p}, 2), got {out.shape}"
        np.testing.assert_allclose(
            out,
            oracle_transform(points, pose),
            atol=1e-12,
            err_msg=f"{p} random points, pose {np.round(pose, 3)}: expected R(theta) p + t",
        )


@grades("transform_points", points=5)
def test_transform_points_invariants(lab):
    """transform_points: identity changes nothing, distances kept, frames chain, input untouched."""
    rng = np.random.default_rng(3)
    points = rng.uniform(-5.0, 5.0, (50, 2))
    # every call gets its own copy: a function that changes its input cannot change the
    # values this test compares with
    np.testing.assert_allclose(
        _f(lab.transform_points(points.copy(), [0.0, 0.0, 0.0])),
        points,
        atol=1e-12,
        err_msg="50 points and the identity pose (0, 0, 0): expected the points unchanged",
    )
    out = _f(lab.transform_points(points.copy(), [3.0, -2.0, 2.5]))
    d_in = np.linalg.norm(points[:, None] - points[None], axis=-1)
    d_out = np.linalg.norm(out[:, None] - out[None], axis=-1)
    np.testing.assert_allclose(
        d_out,
        d_in,
        atol=1e-9,
        err_msg="50 points, pose (3, -2, 2.5): a rigid transform must keep every distance "
        "between points",
    )
    a, b = np.array([0.1, 0.05, 0.3]), np.array([2.0, 1.0, -2.8])
    twice = _f(lab.transform_points(_f(lab.transform_points(points.copy(), a.copy())), b.copy()))
    np.testing.assert_allclose(
        twice,
        oracle_transform(points, compose(b, a)),
        atol=1e-9,
        err_msg="transforming by a = (0.1, 0.05, 0.3), then by b = (2, 1, -2.8): expected the "
        "same as one transform by the composed pose b * a",
    )
    given = points.copy()
    lab.transform_points(given, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(
        given,
        points,
        err_msg="transform_points(points, (1, 1, 1)) changed its points argument in place: "
        "expected the input unchanged (compute a new array)",
    )


@grades("transform_points", points=6)
def test_transform_points_vectorized_over_poses(lab):
    """transform_points: N poses transform the same P points N times, shape (N, P, 2)."""
    rng = np.random.default_rng(4)
    points = rng.normal(0.0, 3.0, (30, 2))
    poses = np.column_stack([rng.uniform(-5, 5, (8, 2)), rng.uniform(-np.pi, np.pi, 8)])
    out = _f(lab.transform_points(points, poses))
    assert out.shape == (8, 30, 2), (
        f"N = 8 poses and P = 30 points: expected (8, 30, 2), got {out.shape}"
    )
    np.testing.assert_allclose(
        out,
        oracle_transform(points, poses),
        atol=1e-12,
        err_msg="30 points and 8 poses: expected out[n] = the points transformed by poses[n]",
    )


TRANSFORM_VALUES = (
    "test_transform_points_hand_computed",
    "test_transform_points_matches_library_on_random_input",
)


@grades("transform_points", points=3)
@pytest.mark.requires(*TRANSFORM_VALUES)
def test_transform_points_rejects_bad_input(lab, refuses):
    """transform_points: points not (P, 2), one (2,) point or a pose not (3,) raise ValueError."""
    with refuses(ValueError, "points of shape (4, 3), not (P, 2)"):
        lab.transform_points(np.ones((4, 3)), [0.0, 0.0, 0.0])
    with refuses(ValueError, "points of shape (2,): a single point must still be (1, 2)"):
        lab.transform_points(np.ones(2), [0.0, 0.0, 0.0])
    with refuses(ValueError, "pose = (1, 2), without theta"):
        lab.transform_points(np.ones((4, 2)), [1.0, 2.0])
    with refuses(ValueError, "pose of shape (5, 4), not (x, y, theta)"):
        lab.transform_points(np.ones((4, 2)), np.ones((5, 4)))


@grades("transform_points", points=5)
@pytest.mark.requires(*TRANSFORM_VALUES)
def test_transform_points_on_the_bundled_bag_and_the_forgotten_mount(lab):
    """transform_points: the bag's scans chained laser -> base_link -> map land on the walls."""
    # Without the base_link -> laser mount (0.1 m forward) they are measurably off.
    bag = _bag()
    scans = bag["scans"]
    odom = PoseTrack(bag["odom_stamps"], bag["odom_poses"]).at(scans.stamps)
    base_in_map = compose(bag["map_from_odom"], odom)
    with_mount, without_mount = [], []
    for k in range(len(scans)):
        pts = scans.endpoints(k)
        in_base = _f(lab.transform_points(pts, bag["mount"]))
        with_mount.append(_f(lab.transform_points(in_base, base_in_map[k])))
        without_mount.append(_f(lab.transform_points(pts, base_in_map[k])))
    good = np.median(_wall_distance(np.concatenate(with_mount)))
    bad = np.median(_wall_distance(np.concatenate(without_mount)))
    assert good < WALL_MEDIAN_BOUND, (
        f"the bag's endpoints chained through the laser mount and the odometry: expected a "
        f"median distance to the walls below {WALL_MEDIAN_BOUND} m, got {good:.3f} m"
    )
    assert bad > 2.0 * good and bad > 0.04, (
        f"forgetting the 0.1 m laser mount should be measurably worse: expected more than "
        f"{max(2 * good, 0.04):.3f} m, got {bad:.3f} m"
    )


# ======================================================================== pose_at (35)
STAMPS = np.array([0.0, 1.0, 3.0])
POSES = np.array([[0.0, 0.0, 0.0], [2.0, 1.0, 1.0], [2.0, 5.0, -1.0]])


@grades("pose_at", points=6)
def test_pose_at_hand_computed(lab):
    """pose_at: halfway through [0, 1] and 3/4 through [1, 3], scalar and vector t (even of one)."""
    out = _f(lab.pose_at(STAMPS, POSES, 0.5))
    assert out.shape == (3,), f"a scalar t gives one pose (3,), got {out.shape}"
    np.testing.assert_allclose(
        out,
        [1.0, 0.5, 0.5],
        atol=1e-12,
        err_msg="t = 0.5 between (0, 0, 0) at 0 s and (2, 1, 1) at 1 s: expected (1, 0.5, 0.5)",
    )
    np.testing.assert_allclose(
        _f(lab.pose_at(STAMPS, POSES, 2.5)),
        [2.0, 4.0, -0.5],
        atol=1e-12,
        err_msg="t = 2.5 between (2, 1, 1) at 1 s and (2, 5, -1) at 3 s: expected (2, 4, -0.5)",
    )
    out = _f(lab.pose_at(STAMPS, POSES, np.array([0.5])))
    assert out.shape == (1, 3), f"t = [0.5], an array of one time: expected (1, 3), got {out.shape}"
    out = _f(lab.pose_at(STAMPS, POSES, np.array([0.25, 2.0])))
    assert out.shape == (2, 3), f"t = [0.25, 2.0]: expected shape (2, 3), got {out.shape}"
    np.testing.assert_allclose(
        out,
        [[0.5, 0.25, 0.25], [2.0, 3.0, 0.0]],
        atol=1e-12,
        err_msg="t = [0.25, 2.0]: expected (0.5, 0.25, 0.25) and (2, 3, 0)",
    )


@grades("pose_at", points=4)
def test_pose_at_recorded_stamps_give_recorded_poses(lab):
    """pose_at: at each recorded stamp, the first and the last included, the recorded pose.

    Also on the smallest track, a single recorded pose, queried at its own stamp.
    """
    rng = np.random.default_rng(5)
    stamps = np.cumsum(rng.uniform(0.01, 0.2, 40)) + 1.7e9  # ROS times are large numbers
    poses = np.column_stack([rng.normal(0, 3, (40, 2)), rng.uniform(-np.pi, np.pi, 40)])
    out = _f(lab.pose_at(stamps, poses, stamps))
    assert out.shape == (40, 3), f"40 stamps queried: expected shape (40, 3), got {out.shape}"
    np.testing.assert_allclose(
        out[:, :2],
        poses[:, :2],
        atol=1e-9,
        err_msg="t = each of 40 recorded stamps (near 1.7e9 s): expected the recorded x, y",
    )
    wrong = angle_error(out[:, 2], poses[:, 2], atol=1e-09)
    assert wrong is None, "t = each of 40 recorded stamps: expected the recorded headings: " + wrong
    for t, pose in ((stamps[0], poses[0]), (stamps[-1], poses[-1])):
        np.testing.assert_allclose(
            _f(lab.pose_at(stamps, poses, t))[:2],
            pose[:2],
            atol=1e-9,
            err_msg=f"scalar t = {t!r}, a recorded stamp at the end of the track: expected "
            "the recorded pose",
        )
    single = _f(lab.pose_at(np.array([5.0]), np.array([[1.0, -2.0, 3.0]]), 5.0))
    np.testing.assert_allclose(
        single,
        [1.0, -2.0, 3.0],
        atol=1e-12,
        err_msg="a track of one pose (1, -2, 3) at 5 s, queried at t = 5: expected that pose",
    )
    single = _f(lab.pose_at(np.array([5.0]), np.array([[1.0, -2.0, 3.0]]), np.array([5.0, 5.0])))
    np.testing.assert_allclose(
        single,
        [[1.0, -2.0, 3.0]] * 2,
        atol=1e-12,
        err_msg="a track of one pose (1, -2, 3) at 5 s, queried at t = [5, 5]: expected that "
        "pose twice, shape (2, 3)",
    )


@grades("pose_at", points=6)
def test_pose_at_turns_the_short_way_across_the_seam(lab):
    """pose_at: from 3.1 to -3.1 rad the heading passes through pi, not through 0."""
    stamps = np.array([10.0, 11.0])
    poses = np.array([[0.0, 0.0, 3.1], [1.0, 0.0, -3.1]])
    mid = _f(lab.pose_at(stamps, poses, 10.5))
    assert abs(angle_diff(mid[2], np.pi)) < 1e-9, (
        f"halfway from 3.1 to -3.1 rad: expected heading pi (the short way), got {mid[2]:.4f}: "
        "interpolating the raw numbers goes through 0, the long way round"
    )
    out = _f(lab.pose_at(stamps, poses, np.array([10.25, 10.75])))
    step = 2 * np.pi - 6.2
    wrong = angle_error(out[:, 2], [3.1 + 0.25 * step, 3.1 + 0.75 * step], atol=1e-09)
    assert wrong is None, (
        "a quarter and three quarters of the way from 3.1 to -3.1 rad: expected "
        "3.1 + 0.25 * 0.083 and 3.1 + 0.75 * 0.083 rad (wrapped): " + wrong
    )
    theta = _f(lab.pose_at(stamps, poses, np.linspace(10.0, 11.0, 101)))[:, 2]
    assert theta.min() >= -np.pi and theta.max() < np.pi, (
        f"101 times from 3.1 to -3.1 rad: expected headings wrapped to [-pi, pi), got "
        f"[{theta.min():.4f}, {theta.max():.4f}]"
    )
    q = _f(lab.pose_at([0.0, 2.0], [[0.0, 0.0, -3.0], [0.0, 0.0, 3.0]], 1.0))
    assert abs(angle_diff(q[2], np.pi)) < 1e-9, (
        f"halfway from -3.0 to 3.0 rad (clockwise through -pi): expected heading +-pi, got "
        f"{q[2]:.4f}"
    )


@grades("pose_at", points=4)
def test_pose_at_far_from_zero_headings_and_many_turns(lab):
    """pose_at: headings recorded unwrapped (several turns) still interpolate the short way."""
    # An integrating odometry can report theta = 20 rad; 20 -> 20.2 is a 0.2 rad turn.
    stamps = np.array([0.0, 1.0])
    poses = np.array([[0.0, 0.0, 20.0], [0.0, 0.0, 20.2]])
    got = _f(lab.pose_at(stamps, poses, 0.5))[2]
    expected = float(angle_diff(20.1, 0.0))
    assert abs(angle_diff(got, expected)) < 1e-9 and -np.pi <= got < np.pi, (
        f"halfway from 20.0 to 20.2 rad: expected {expected:.4f} rad (20.1 wrapped to "
        f"[-pi, pi)), got {got:.4f}"
    )


@grades("pose_at", points=5)
def test_pose_at_matches_library_on_random_tracks(lab):
    """pose_at: 1000 random times on a 200-pose track with many seam crossings match tf2."""
    rng = np.random.default_rng(6)
    stamps = np.cumsum(rng.uniform(0.02, 0.1, 200))
    steps = np.column_stack([rng.normal(0, 0.05, (200, 2)), rng.normal(0, 0.8, 200)])
    poses = np.cumsum(steps, axis=0)
    poses[:, 2] = (poses[:, 2] + np.pi) % (2 * np.pi) - np.pi  # many seam crossings
    t = rng.uniform(stamps[0], stamps[-1], 1000)
    out = _f(lab.pose_at(stamps, poses, t))
    assert out.shape == (1000, 3), f"1000 query times: expected shape (1000, 3), got {out.shape}"
    expected = PoseTrack(stamps, poses).at(t)
    np.testing.assert_allclose(
        out[:, :2],
        expected[:, :2],
        atol=1e-9,
        err_msg="1000 random times: expected x, y linearly interpolated between the neighbours",
    )
    wrong = angle_error(out[:, 2], expected[:, 2], atol=1e-09)
    assert wrong is None, (
        "1000 random times: expected headings interpolated the short way round: " + wrong
    )


POSE_VALUES = ("test_pose_at_hand_computed", "test_pose_at_matches_library_on_random_tracks")


@grades("pose_at", points=3)
@pytest.mark.requires(*POSE_VALUES)
def test_pose_at_refuses_to_extrapolate(lab, refuses):
    """pose_at: a time before the first or after the last stamp raises ValueError."""
    with refuses(ValueError, "t = -0.1, before the first stamp 0 (no extrapolation)"):
        lab.pose_at(STAMPS, POSES, -0.1)
    with refuses(ValueError, "t = 3.001, after the last stamp 3 (no extrapolation)"):
        lab.pose_at(STAMPS, POSES, 3.001)
    with refuses(ValueError, "t = (0.5, 1.5, 4.0): one time after the last stamp 3 is enough"):
        lab.pose_at(STAMPS, POSES, np.array([0.5, 1.5, 4.0]))


@grades("pose_at", points=3)
@pytest.mark.requires(*POSE_VALUES)
def test_pose_at_rejects_bad_input(lab, refuses):
    """pose_at: unsorted stamps, one pose too few, or poses without theta raise ValueError."""
    with refuses(ValueError, "stamps = (0, 2, 1), not sorted"):
        lab.pose_at(np.array([0.0, 2.0, 1.0]), POSES, 0.5)
    with refuses(ValueError, "3 stamps for 2 poses (one pose per stamp)"):
        lab.pose_at(STAMPS, POSES[:2], 0.5)
    with refuses(ValueError, "poses of shape (3, 2), without theta"):
        lab.pose_at(STAMPS, POSES[:, :2], 0.5)


@grades("pose_at", points=2)
@pytest.mark.requires(*POSE_VALUES)
def test_pose_at_rejects_duplicate_stamps(lab, refuses):
    """pose_at: two poses at the same stamp (not strictly increasing) raise ValueError."""
    with refuses(ValueError, "stamps = (0, 1, 1), two poses at the same stamp"):
        lab.pose_at(np.array([0.0, 1.0, 1.0]), POSES, 0.5)


@grades("pose_at", points=2)
@pytest.mark.requires(*POSE_VALUES)
def test_pose_at_on_the_bundled_bag(lab):
    """pose_at: odometry at the bag's scan stamps places the scans on the walls."""
    bag = _bag()
    scans, stamps, poses = bag["scans"], bag["odom_stamps"], bag["odom_poses"]
    track = PoseTrack(stamps, poses)
    half = 0.5 * (stamps[1:] + stamps[:-1])
    out = _f(lab.pose_at(stamps, poses, half))
    np.testing.assert_allclose(
        out[:, :2],
        track.at(half)[:, :2],
        atol=1e-9,
        err_msg="the bag's odometry halfway between messages: expected the interpolated x, y",
    )
    odom = _f(lab.pose_at(stamps, poses, scans.stamps))
    assert odom.shape == (len(scans), 3), (
        f"{len(scans)} scan stamps: expected shape ({len(scans)}, 3), got {odom.shape}"
    )
    laser = _laser_poses_in_map(odom, bag["mount"])
    cloud = np.concatenate([scans.endpoints(k, laser[k]) for k in range(len(scans))])
    median = np.median(_wall_distance(cloud))
    assert median < WALL_MEDIAN_BOUND, (
        f"the bag's scans placed at your odometry poses: expected a median distance to the "
        f"walls below {WALL_MEDIAN_BOUND} m, got {median:.3f} m"
    )
