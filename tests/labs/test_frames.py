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

Points: scan_to_cartesian 30, transform_points 35, pose_at 35.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy import ndimage

from robolab import DATA_DIR
from robolab.bag import BagReader, PoseTrack, Scans, laser_pose_in_base
from robolab.geometry import angle_diff, compose
from robolab.geometry import transform_points as oracle_transform
from robolab.maps import load_map

grades = pytest.mark.grades

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
    assert pts.ndim == 2 and pts.shape[1] == 2, f"expected points of shape (P, 2), got {pts.shape}"
    assert np.all(np.isfinite(pts)), "endpoints must be finite: invalid ranges must be dropped"
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
    # Beams at 0, 90, 180 and -90 degrees: (2, 0), (0, 1), (-3, 0), (0, -0.5).
    ranges = [2.0, 1.0, 3.0, 0.5]
    angles = [0.0, np.pi / 2, np.pi, -np.pi / 2]
    out = _f(lab.scan_to_cartesian(ranges, angles, 0.1, 10.0))
    assert out.shape == (4, 2)
    np.testing.assert_allclose(out, [[2.0, 0.0], [0.0, 1.0], [-3.0, 0.0], [0.0, -0.5]], atol=1e-12)
    # 45 degrees, sqrt(2) m: (1, 1); 150 degrees, 2 m: (-sqrt(3), 1).
    out = _f(
        lab.scan_to_cartesian(np.array([np.sqrt(2.0), 2.0]), np.radians([45.0, 150.0]), 0.0, 5.0)
    )
    np.testing.assert_allclose(out, [[1.0, 1.0], [-np.sqrt(3.0), 1.0]], atol=1e-12)


@grades("scan_to_cartesian", points=6)
def test_scan_to_cartesian_matches_library_on_random_scans(lab):
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
            f"{b} beams: expected shape {expected.shape}, got {out.shape}"
        )
        np.testing.assert_allclose(out, expected, atol=1e-12)


@grades("scan_to_cartesian", points=8)
def test_scan_to_cartesian_drops_every_kind_of_invalid_return(lab):
    # Only beams 1 (1.0 m at 90 deg) and 5 (4.0 m at 0 deg) are real returns; the rest are
    # 0, +inf, NaN, below range_min (0.05), above range_max (8.0) and -inf.
    ranges = [0.0, 1.0, np.inf, np.nan, 0.04, 4.0, 8.5, -np.inf]
    angles = [0.1, np.pi / 2, 0.3, 0.4, 0.5, 0.0, 0.7, 0.8]
    out = _f(lab.scan_to_cartesian(ranges, angles, 0.05, 8.0))
    assert out.shape == (2, 2), (
        f"expected the 2 valid beams only, got {out.shape[0]} points: 0, inf, NaN and "
        "out-of-range readings mean 'no return' and must be dropped"
    )
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, [[0.0, 1.0], [4.0, 0.0]], atol=1e-12)
    # No returned point may lie outside the valid range band: nothing invalid became a hit.
    rng = np.random.default_rng(1)
    ranges = rng.choice([0.0, np.inf, np.nan, 0.01, 9.0, 2.5, 7.9, 0.06], size=500)
    out = _f(lab.scan_to_cartesian(ranges, np.linspace(-np.pi, np.pi, 500), 0.05, 8.0))
    valid = np.isin(ranges, [2.5, 7.9, 0.06])
    assert out.shape == (valid.sum(), 2)
    np.testing.assert_allclose(np.hypot(out[:, 0], out[:, 1]), ranges[valid], rtol=1e-12)


@grades("scan_to_cartesian", points=3)
def test_scan_to_cartesian_no_valid_beam_gives_empty_points(lab):
    out = _f(lab.scan_to_cartesian([np.inf, 0.0, np.nan, 20.0], [0.0, 0.1, 0.2, 0.3], 0.1, 10.0))
    assert out.shape == (0, 2), f"no valid beam: expected shape (0, 2), got {out.shape}"


@grades("scan_to_cartesian", points=4)
def test_scan_to_cartesian_rejects_bad_input(lab):
    with pytest.raises(ValueError):  # one angle per range
        lab.scan_to_cartesian([1.0, 2.0, 3.0], [0.0, 0.1], 0.1, 10.0)
    with pytest.raises(ValueError):  # range_min must be below range_max
        lab.scan_to_cartesian([1.0, 2.0], [0.0, 0.1], 5.0, 1.0)
    with pytest.raises(ValueError):  # one scan (B,), not a matrix
        lab.scan_to_cartesian(np.ones((2, 3)), np.zeros((2, 3)), 0.1, 10.0)


@grades("scan_to_cartesian", points=4)
def test_scan_to_cartesian_on_the_bundled_bag(lab):
    # The student's endpoints, placed with the library at the odometry poses of each scan.
    bag = _bag()
    scans = bag["scans"]
    odom = PoseTrack(bag["odom_stamps"], bag["odom_poses"]).at(scans.stamps)
    laser = _laser_poses_in_map(odom, bag["mount"])
    cloud = []
    for k in range(len(scans)):
        pts = _f(
            lab.scan_to_cartesian(scans.ranges[k], scans.angles, scans.range_min, scans.range_max)
        )
        # sensor_msgs says to discard r > range_max; whether a max-range reading
        # (r == range_max, a failed return) is kept is a convention: accept both.
        strict = int(scans.valid[k].sum())
        closed = strict + int(np.sum(scans.ranges[k] == scans.range_max))
        assert pts.ndim == 2 and pts.shape[1] == 2 and pts.shape[0] in (strict, closed), (
            f"scan {k}: {strict} valid beams ({closed} counting max-range readings), "
            f"got {pts.shape[0]} points"
        )
        cloud.append(oracle_transform(pts, laser[k]))
    median = np.median(_wall_distance(np.concatenate(cloud)))
    assert median < WALL_MEDIAN_BOUND, f"median distance to the walls {median:.3f} m"


# =============================================================== transform_points (35)
@grades("transform_points", points=6)
def test_transform_points_hand_computed(lab):
    # Child at (1, 2) turned 90 degrees: its x axis is the parent's y axis.
    # (1, 0) -> (1, 3); (0, 1) -> (0, 2); (2, -1) -> (1 + 1, 2 + 2) = (2, 4).
    out = _f(lab.transform_points([[1.0, 0.0], [0.0, 1.0], [2.0, -1.0]], [1.0, 2.0, np.pi / 2]))
    assert out.shape == (3, 2)
    np.testing.assert_allclose(out, [[1.0, 3.0], [0.0, 2.0], [2.0, 4.0]], atol=1e-12)
    # Rotate first, then translate: a laser 0.1 m ahead of a robot at (5, 5) facing west
    # (pi) sees a wall 1 m ahead at (5 - 0.1 - 1, 5) = (3.9, 5).
    out = _f(lab.transform_points(np.array([[1.0, 0.0]]), np.array([4.9, 5.0, np.pi])))
    np.testing.assert_allclose(out, [[3.9, 5.0]], atol=1e-12)


@grades("transform_points", points=6)
def test_transform_points_matches_library_on_random_input(lab):
    rng = np.random.default_rng(2)
    for p in (1, 5, 400):
        points = rng.normal(0.0, 4.0, (p, 2))
        pose = np.array([rng.uniform(-10, 10), rng.uniform(-10, 10), rng.uniform(-np.pi, np.pi)])
        out = _f(lab.transform_points(points, pose))
        assert out.shape == (p, 2)
        np.testing.assert_allclose(out, oracle_transform(points, pose), atol=1e-12)


@grades("transform_points", points=5)
def test_transform_points_invariants(lab):
    rng = np.random.default_rng(3)
    points = rng.uniform(-5.0, 5.0, (50, 2))
    # the identity pose changes nothing
    np.testing.assert_allclose(
        _f(lab.transform_points(points, [0.0, 0.0, 0.0])), points, atol=1e-12
    )
    # a rigid transform keeps every distance between points
    out = _f(lab.transform_points(points, [3.0, -2.0, 2.5]))
    d_in = np.linalg.norm(points[:, None] - points[None], axis=-1)
    d_out = np.linalg.norm(out[:, None] - out[None], axis=-1)
    np.testing.assert_allclose(d_out, d_in, atol=1e-9)
    # chaining two frames equals one transform with the composed pose (laser -> base -> odom)
    a, b = np.array([0.1, 0.05, 0.3]), np.array([2.0, 1.0, -2.8])
    twice = _f(lab.transform_points(_f(lab.transform_points(points, a)), b))
    np.testing.assert_allclose(twice, oracle_transform(points, compose(b, a)), atol=1e-9)
    # the input is not modified
    before = points.copy()
    lab.transform_points(points, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(points, before)


@grades("transform_points", points=4)
def test_transform_points_vectorized_over_poses(lab):
    rng = np.random.default_rng(4)
    points = rng.normal(0.0, 3.0, (30, 2))
    poses = np.column_stack([rng.uniform(-5, 5, (8, 2)), rng.uniform(-np.pi, np.pi, 8)])
    out = _f(lab.transform_points(points, poses))
    assert out.shape == (8, 30, 2), (
        f"N = 8 poses and P = 30 points: expected (8, 30, 2), got {out.shape}"
    )
    np.testing.assert_allclose(out, oracle_transform(points, poses), atol=1e-12)


@grades("transform_points", points=4)
def test_transform_points_rejects_bad_input(lab):
    with pytest.raises(ValueError):  # points must be (P, 2)
        lab.transform_points(np.ones((4, 3)), [0.0, 0.0, 0.0])
    with pytest.raises(ValueError):  # a single point must still be (1, 2)
        lab.transform_points(np.ones(2), [0.0, 0.0, 0.0])
    with pytest.raises(ValueError):  # a pose is (x, y, theta)
        lab.transform_points(np.ones((4, 2)), [1.0, 2.0])
    with pytest.raises(ValueError):
        lab.transform_points(np.ones((4, 2)), np.ones((5, 4)))


@grades("transform_points", points=10)
def test_transform_points_on_the_bundled_bag_and_the_forgotten_mount(lab):
    # Library endpoints and odometry; the student's transform chains laser -> base_link ->
    # odom -> map. Correct: endpoints on the walls. Without the base_link -> laser mount
    # (0.1 m forward): measurably off.
    bag = _bag()
    scans = bag["scans"]
    np.testing.assert_allclose(bag["mount"], [0.1, 0.0, 0.0], atol=1e-9)  # data/README.md
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
    assert good < WALL_MEDIAN_BOUND, f"median distance to the walls {good:.3f} m"
    # Forgetting the mount shifts every endpoint 0.1 m; the walls across the heading show it.
    assert bad > 2.0 * good and bad > 0.04, (
        f"forgetting the 0.1 m laser mount should be measurably worse: {bad:.3f} vs {good:.3f} m"
    )


# ======================================================================== pose_at (35)
STAMPS = np.array([0.0, 1.0, 3.0])
POSES = np.array([[0.0, 0.0, 0.0], [2.0, 1.0, 1.0], [2.0, 5.0, -1.0]])


@grades("pose_at", points=6)
def test_pose_at_hand_computed(lab):
    # t = 0.5: halfway through [0, 1] -> (1, 0.5, 0.5).
    out = _f(lab.pose_at(STAMPS, POSES, 0.5))
    assert out.shape == (3,), f"a scalar t gives one pose (3,), got {out.shape}"
    np.testing.assert_allclose(out, [1.0, 0.5, 0.5], atol=1e-12)
    # t = 2.5: 3/4 through [1, 3] -> (2, 1 + 0.75 * 4, 1 + 0.75 * (-2)) = (2, 4, -0.5).
    np.testing.assert_allclose(_f(lab.pose_at(STAMPS, POSES, 2.5)), [2.0, 4.0, -0.5], atol=1e-12)
    # vectorized: t = [0.25, 2.0] -> (0.5, 0.25, 0.25) and (2, 3, 0).
    out = _f(lab.pose_at(STAMPS, POSES, np.array([0.25, 2.0])))
    assert out.shape == (2, 3)
    np.testing.assert_allclose(out, [[0.5, 0.25, 0.25], [2.0, 3.0, 0.0]], atol=1e-12)


@grades("pose_at", points=4)
def test_pose_at_recorded_stamps_give_recorded_poses(lab):
    rng = np.random.default_rng(5)
    stamps = np.cumsum(rng.uniform(0.01, 0.2, 40)) + 1.7e9  # ROS times are large numbers
    poses = np.column_stack([rng.normal(0, 3, (40, 2)), rng.uniform(-np.pi, np.pi, 40)])
    out = _f(lab.pose_at(stamps, poses, stamps))
    assert out.shape == (40, 3)
    np.testing.assert_allclose(out[:, :2], poses[:, :2], atol=1e-9)
    np.testing.assert_allclose(angle_diff(out[:, 2], poses[:, 2]), 0.0, atol=1e-9)
    first, last = (
        _f(lab.pose_at(stamps, poses, stamps[0])),
        _f(lab.pose_at(stamps, poses, stamps[-1])),
    )
    np.testing.assert_allclose(first[:2], poses[0, :2], atol=1e-9)
    np.testing.assert_allclose(last[:2], poses[-1, :2], atol=1e-9)


@grades("pose_at", points=6)
def test_pose_at_turns_the_short_way_across_the_seam(lab):
    stamps = np.array([10.0, 11.0])
    poses = np.array([[0.0, 0.0, 3.1], [1.0, 0.0, -3.1]])
    # 3.1 -> -3.1 is a turn of 2 pi - 6.2 = 0.0832 rad counter-clockwise, through pi.
    mid = _f(lab.pose_at(stamps, poses, 10.5))
    np.testing.assert_allclose(mid[:2], [0.5, 0.0], atol=1e-12)
    assert abs(angle_diff(mid[2], np.pi)) < 1e-9, (
        f"halfway from 3.1 to -3.1 rad the heading is pi (the short way), got {mid[2]:.4f}: "
        "interpolating the raw numbers goes through 0, the long way round"
    )
    out = _f(lab.pose_at(stamps, poses, np.array([10.25, 10.75])))
    step = 2 * np.pi - 6.2
    np.testing.assert_allclose(
        angle_diff(out[:, 2], [3.1 + 0.25 * step, 3.1 + 0.75 * step]), 0.0, atol=1e-9
    )
    # returned headings are wrapped to [-pi, pi)
    t = np.linspace(10.0, 11.0, 101)
    theta = _f(lab.pose_at(stamps, poses, t))[:, 2]
    assert theta.min() >= -np.pi and theta.max() < np.pi, "headings must be wrapped to [-pi, pi)"
    # and clockwise across the seam: -3.0 -> 3.0 turns 0.283 rad clockwise through -pi
    q = _f(lab.pose_at([0.0, 2.0], [[0.0, 0.0, -3.0], [0.0, 0.0, 3.0]], 1.0))
    assert abs(angle_diff(q[2], np.pi)) < 1e-9


@grades("pose_at", points=6)
def test_pose_at_matches_library_on_random_tracks(lab):
    rng = np.random.default_rng(6)
    stamps = np.cumsum(rng.uniform(0.02, 0.1, 200))
    steps = np.column_stack([rng.normal(0, 0.05, (200, 2)), rng.normal(0, 0.8, 200)])
    poses = np.cumsum(steps, axis=0)
    poses[:, 2] = (poses[:, 2] + np.pi) % (2 * np.pi) - np.pi  # many seam crossings
    t = rng.uniform(stamps[0], stamps[-1], 1000)
    out = _f(lab.pose_at(stamps, poses, t))
    assert out.shape == (1000, 3)
    expected = PoseTrack(stamps, poses).at(t)
    np.testing.assert_allclose(out[:, :2], expected[:, :2], atol=1e-9)
    np.testing.assert_allclose(angle_diff(out[:, 2], expected[:, 2]), 0.0, atol=1e-9)


@grades("pose_at", points=4)
def test_pose_at_refuses_to_extrapolate(lab):
    with pytest.raises(ValueError):
        lab.pose_at(STAMPS, POSES, -0.1)
    with pytest.raises(ValueError):
        lab.pose_at(STAMPS, POSES, 3.001)
    with pytest.raises(ValueError):  # one bad time in many is enough
        lab.pose_at(STAMPS, POSES, np.array([0.5, 1.5, 4.0]))


@grades("pose_at", points=4)
def test_pose_at_rejects_bad_input(lab):
    with pytest.raises(ValueError):  # unsorted stamps
        lab.pose_at(np.array([0.0, 2.0, 1.0]), POSES, 0.5)
    with pytest.raises(ValueError):  # one pose per stamp
        lab.pose_at(STAMPS, POSES[:2], 0.5)
    with pytest.raises(ValueError):  # poses are (x, y, theta)
        lab.pose_at(STAMPS, POSES[:, :2], 0.5)


@grades("pose_at", points=5)
def test_pose_at_on_the_bundled_bag(lab):
    # Odometry at every scan stamp and halfway between odometry messages, against the
    # library; then the endpoints placed with the student's poses land on the walls.
    bag = _bag()
    scans, stamps, poses = bag["scans"], bag["odom_stamps"], bag["odom_poses"]
    track = PoseTrack(stamps, poses)
    half = 0.5 * (stamps[1:] + stamps[:-1])
    out = _f(lab.pose_at(stamps, poses, half))
    np.testing.assert_allclose(out[:, :2], track.at(half)[:, :2], atol=1e-9)
    np.testing.assert_allclose(angle_diff(out[:, 2], track.at(half)[:, 2]), 0.0, atol=1e-9)
    odom = _f(lab.pose_at(stamps, poses, scans.stamps))
    assert odom.shape == (len(scans), 3)
    laser = _laser_poses_in_map(odom, bag["mount"])
    cloud = np.concatenate([scans.endpoints(k, laser[k]) for k in range(len(scans))])
    median = np.median(_wall_distance(cloud))
    assert median < WALL_MEDIAN_BOUND, f"median distance to the walls {median:.3f} m"
