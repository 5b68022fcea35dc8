"""Tests of robolab.floorplan, robolab.sim, `robolab data` and the bundled data in data/."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from scipy import ndimage

from robolab import DATA_DIR, sim
from robolab.bag import BagReader, laser_pose_in_base
from robolab.floorplan import TOP_ROOM_X, office_floorplan
from robolab.geometry import compose, relative, transform_points, wrap_angle
from robolab.maps import OccupancyGrid, load_map
from robolab.raycast import cast_rays

RANGE_F32 = dict(rtol=0, atol=0)  # LaserScan ranges are float32 in the bag and in SimRun: exact


@pytest.fixture(scope="module")
def office() -> OccupancyGrid:
    return office_floorplan()


@pytest.fixture(scope="module")
def short_run(office) -> sim.SimRun:
    """4 s of the mapping route: leaves the corridor's west end heading east."""
    return sim.mapping_run(duration=4.0)


def _distance_to_obstacle(grid: OccupancyGrid, xy: np.ndarray) -> np.ndarray:
    """Metres from points to the nearest occupied cell centre (brute force via the EDT)."""
    dist, (ri, ci) = ndimage.distance_transform_edt(~grid.occupied, return_indices=True)
    rc = grid.world_to_cell(xy)
    ok = grid.contains_cell(rc)
    out = np.full(len(xy), np.inf)
    centre = grid.cell_to_world(np.stack([ri[rc[ok, 0], rc[ok, 1]], ci[rc[ok, 0], rc[ok, 1]]], -1))
    out[ok] = np.hypot(*(centre - xy[ok]).T)
    return out


# -- the floor plan -------------------------------------------------------------------
def test_floorplan_geometry_and_values(office):
    assert office.shape == (260, 420)
    assert office.resolution == 0.05
    np.testing.assert_allclose(office.origin, (-0.5, -0.5, 0.0))
    assert set(np.unique(office.data)) == {-1.0, 0.0, 1.0}
    assert office.width == pytest.approx(21.0) and office.height == pytest.approx(13.0)
    # the building (20 m x 12 m) is known; outside the outer walls is unknown
    assert office.data[0, 0] == -1 and office.data[-1, -1] == -1
    assert 0.5 < office.free.mean() < 0.8


def test_floorplan_is_deterministic_and_rejects_coarse_resolution(office):
    np.testing.assert_array_equal(office_floorplan().data, office.data)
    assert office_floorplan(0.1).shape == (130, 210)
    with pytest.raises(ValueError, match="resolution"):
        office_floorplan(0.2)
    with pytest.raises(ValueError, match="resolution"):
        office_floorplan(-1.0)


def test_floorplan_walls_are_tight(office):
    # Free space inside the building never touches unknown space, not even
    # diagonally: no ray or robot can slip through a wall.
    labels, _ = ndimage.label(office.data != 1.0, structure=np.ones((3, 3)))
    inside = labels[
        office.world_to_cell([[1.0, 6.0]])[0][0], office.world_to_cell([[1.0, 6.0]])[0][1]
    ]
    assert not np.any(office.unknown & (labels == inside))
    # every wall is at least 2 cells thick along both axes
    occ = office.occupied
    thin_x = occ[:, 1:-1] & ~occ[:, :-2] & ~occ[:, 2:]
    thin_y = occ[1:-1, :] & ~occ[:-2, :] & ~occ[2:, :]
    assert not thin_x.any() and not thin_y.any()


def test_floorplan_rooms_are_identical_and_reachable(office):
    # The four north offices are the same pattern shifted by 5 m: global
    # localization cannot tell them apart from inside.
    def cell(v):  # metres -> cell index along either axis (origin -0.5 m on both)
        return int(round((v + 0.5) / office.resolution))

    r0, r1 = cell(7.2), cell(11.9)
    cols = [cell(x + 0.1) for x in TOP_ROOM_X]
    width = cols[1] - cols[0] - 4  # room interior without the divider walls
    assert office.occupied[r0 - 1, cols[0] : cols[0] + width].mean() > 0.7  # the corridor wall
    assert not office.occupied[r0, cols[0] : cols[0] + width].all()
    patches = [office.data[r0:r1, c : c + width] for c in cols]
    for p in patches[1:]:
        np.testing.assert_array_equal(p, patches[0])
    # all free space of the building is one connected region (every door opens)
    labels, n = ndimage.label(office.free)
    sizes = np.bincount(labels.ravel())[1:]
    assert sizes.max() / sizes.sum() > 0.999


def test_office_map_round_trips_through_map_server(tmp_path, office):
    paths = sim.make_data(tmp_path, only=["office"], progress=False)
    assert {p.name for p in paths} == {"office.yaml", "office.pgm"}
    back = load_map(tmp_path / "office.yaml")
    np.testing.assert_array_equal(back.data, office.data)
    np.testing.assert_allclose(back.origin, office.origin)
    assert back.resolution == office.resolution


# -- motion ---------------------------------------------------------------------------
def test_follow_route_reaches_waypoints_within_limits():
    route = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]
    c = sim.Controller()
    poses, cmds, reached = sim.follow_route(
        route, (0.0, 0.0, 0.0), duration=20.0, dt=0.01, controller=c
    )
    assert reached.all()
    assert np.hypot(*(poses[-1, :2] - route[-1])) < c.tolerance
    assert np.all(cmds[:, 0] >= 0) and np.all(cmds[:, 0] <= c.v_max + 1e-12)
    assert np.all(np.abs(cmds[:, 1]) <= c.w_max + 1e-12)
    assert np.all(np.abs(np.diff(cmds[:, 0])) <= c.a_max * 0.01 + 1e-12)
    # the arc model is exact: a pose follows from the previous one and the command
    k = 500
    v, w = cmds[k]
    expected = compose(
        poses[k], [v / w * np.sin(w * 0.01), v / w * (1 - np.cos(w * 0.01)), w * 0.01]
    )
    np.testing.assert_allclose(poses[k + 1], expected, atol=1e-12)


def test_follow_route_euler_matches_seed_000_transition_model():
    poses, cmds, _ = sim.follow_route(
        [[5.0, 5.0], [5.0, 9.0]], (5.0, 5.0, 0.3), duration=3.0, dt=0.1, model="euler"
    )
    x, y, th = poses[:-1].T
    v, w = cmds.T
    np.testing.assert_allclose(poses[1:, 0], x + v * np.cos(th) * 0.1, atol=1e-12)
    np.testing.assert_allclose(poses[1:, 1], y + v * np.sin(th) * 0.1, atol=1e-12)
    np.testing.assert_allclose(poses[1:, 2], wrap_angle(th + w * 0.1), atol=1e-12)


def test_follow_route_bad_input():
    with pytest.raises(ValueError, match="route"):
        sim.follow_route([[0.0, 0.0, 0.0]], (0, 0, 0), duration=1.0, dt=0.1)
    with pytest.raises(ValueError, match="model"):
        sim.follow_route([[1.0, 0.0]], (0, 0, 0), duration=1.0, dt=0.1, model="rk4")
    with pytest.raises(ValueError, match="rng"):
        sim.follow_route([[1.0, 0.0]], (0, 0, 0), duration=1.0, dt=0.1, control_noise=(0.1, 0.0))
    with pytest.raises(ValueError, match="duration"):
        sim.follow_route([[1.0, 0.0]], (0, 0, 0), duration=0.0, dt=0.1)


def test_odometry_without_noise_is_exact_and_bias_drifts():
    poses, _, _ = sim.follow_route(
        [[3.0, 0.0], [3.0, 3.0]], (0.0, 0.0, 0.0), duration=15.0, dt=0.05
    )
    perfect = sim.OdometryNoise(
        alpha1=0, alpha2=0, alpha3=0, alpha4=0, scale_right=1.0, wheel_base_scale=1.0
    )
    odo = sim.odometry_from_truth(poses, perfect, np.random.default_rng(0))
    np.testing.assert_allclose(odo, relative(poses[0], poses), atol=1e-9)
    # a right wheel that reports 1 % too much turns every straight line to the left
    bent = sim.OdometryNoise(
        alpha1=0, alpha2=0, alpha3=0, alpha4=0, scale_right=1.01, wheel_base_scale=1.0
    )
    odo = sim.odometry_from_truth(poses, bent, np.random.default_rng(0))
    err = wrap_angle(odo[:, 2] - relative(poses[0], poses)[:, 2])
    moving = np.hypot(*np.diff(poses[:, :2], axis=0).T) > 0
    assert err[-1] > 0.05 and np.all(np.diff(err)[moving] >= -1e-12)


def test_odometry_noise_matches_table_5_6_variance():
    # straight steps of 0.1 m: trans variance alpha3 * 0.01 per step
    steps = 20000
    poses = np.zeros((steps + 1, 3))
    poses[:, 0] = 0.1 * np.arange(steps + 1)
    noise = sim.OdometryNoise(
        alpha1=0.0, alpha2=0.0, alpha3=0.04, alpha4=0.0, scale_right=1.0, wheel_base_scale=1.0
    )
    odo = sim.odometry_from_truth(poses, noise, np.random.default_rng(1))
    trans = np.hypot(*np.diff(odo[:, :2], axis=0).T)
    # std of a sample std from n = 20000 normals is sigma / sqrt(2 n) = 0.5 %; allow 4 %
    assert trans.mean() == pytest.approx(0.1, abs=4 * 0.02 / np.sqrt(steps))
    assert trans.std() == pytest.approx(0.02, rel=0.04)


# -- sensing --------------------------------------------------------------------------
def test_scan_noise_mixture():
    laser = sim.LaserModel()
    z = np.full((400, 360), 3.0)
    z[:, :60] = laser.range_max  # nothing in range
    ranges, kind = sim.scan_noise(z, laser, np.random.default_rng(3))
    assert ranges.dtype == np.float32 and kind.dtype == np.int8
    n = kind.size
    frac = np.bincount(kind.ravel(), minlength=4) / n
    # binomial standard error sqrt(p (1 - p) / n) <= 0.0015; allow 5 of them
    np.testing.assert_allclose(frac, laser.weights, atol=0.0075)
    hit, short, fail, rand = (kind == k for k in range(4))
    in_range = np.zeros_like(hit)
    in_range[:, 60:] = True
    assert np.all(np.isinf(ranges[hit & ~in_range]))  # REP-117: nothing in range -> +inf
    assert np.all(ranges[fail] == laser.range_max)  # failures: exactly range_max
    h = ranges[hit & in_range].astype(float)
    assert abs(h.mean() - 3.0) < 0.002 and h.std() == pytest.approx(laser.sigma_hit, rel=0.05)
    assert np.all((ranges[short & in_range] >= 0) & (ranges[short & in_range] <= 3.0 + 1e-6))
    assert np.all(ranges[short & ~in_range] <= laser.range_max)
    assert np.all((ranges[rand] >= 0) & (ranges[rand] < laser.range_max))
    assert not np.isnan(ranges).any()


def test_laser_model_validation():
    assert sim.LaserModel().angles.shape == (360,)
    assert sim.LaserModel().angle_increment == pytest.approx(np.pi / 180)
    with pytest.raises(ValueError, match="range_min"):
        sim.LaserModel(range_min=9.0, range_max=8.0)
    with pytest.raises(ValueError, match="z_hit"):
        sim.LaserModel(z_hit=-1.0)
    with pytest.raises(ValueError, match="n_beams"):
        sim.LaserModel(n_beams=0)


# -- simulate -------------------------------------------------------------------------
def test_short_run_shapes_and_rates(short_run):
    r = short_run
    assert r.t.shape == (81,) and r.scan_t.shape == (41,)
    np.testing.assert_allclose(np.diff(r.t), 1 / 20)
    np.testing.assert_allclose(np.diff(r.scan_t), 1 / 10)
    assert r.ranges.shape == r.true_ranges.shape == r.beam_kind.shape == (41, 360)
    assert r.ranges.dtype == np.float32
    np.testing.assert_array_equal(r.odom_poses[0], 0.0)
    np.testing.assert_allclose(r.laser_offset, (0.1, 0.0, 0.0))
    # scans are taken at odometry samples
    np.testing.assert_allclose(r.scan_poses, r.true_poses[::2])


def test_ground_truth_stays_in_free_space(office, short_run):
    for run in (short_run, sim.localization_run(duration=3.0)):
        d = _distance_to_obstacle(office, run.true_poses[:, :2])
        assert d.min() > 0.25
        rc = office.world_to_cell(run.true_poses[:, :2])
        assert office.free[rc[:, 0], rc[:, 1]].all()


def test_bundled_routes_are_collision_free(office):
    # the whole routes, without sensing: truth only (fast)
    clear = sim.clearance_field(office)
    for route, start, duration in (
        (sim.MAPPING_ROUTE, sim.MAPPING_START, sim.MAPPING_DURATION),
        (sim.LOCALIZATION_ROUTE, sim.LOCALIZATION_START, sim.LOCALIZATION_DURATION),
    ):
        poses, _, _ = sim.follow_route(route, start, duration=duration, dt=0.01)
        rc = office.world_to_cell(poses[:, :2])
        assert clear[rc[:, 0], rc[:, 1]].min() >= 0.2


def test_simulate_rejects_a_route_through_a_wall(office):
    with pytest.raises(ValueError, match="route collides"):
        sim.simulate(office, [[1.0, 6.0], [1.0, 9.0]], duration=5.0, rng=np.random.default_rng(0))


def test_simulate_bad_input(office):
    with pytest.raises(TypeError, match="grid"):
        sim.simulate(np.zeros((3, 3)), [[1, 6], [3, 6]], duration=1.0, rng=np.random.default_rng(0))
    with pytest.raises(TypeError, match="rng"):
        sim.simulate(office, [[1, 6], [3, 6]], duration=1.0, rng=0)
    with pytest.raises(ValueError, match="multiple"):
        sim.simulate(
            office, [[1, 6], [3, 6]], duration=1.0, rng=np.random.default_rng(0), odom_rate=30.0
        )


def test_scans_from_ground_truth_agree_with_the_map(office, short_run):
    r = short_run
    hit = (r.beam_kind == 0) & np.isfinite(r.ranges)
    ends = []
    for k in range(len(r.scan_t)):
        a = r.angles[hit[k]]
        q = np.stack([r.ranges[k, hit[k]] * np.cos(a), r.ranges[k, hit[k]] * np.sin(a)], -1)
        ends.append(transform_points(q, r.laser_poses[k]))
    d = _distance_to_obstacle(office, np.concatenate(ends))
    # an endpoint lies on the face of its cell, half a cell (2.5 cm) from the centre, +- sigma_hit
    assert np.median(d) < 0.05
    assert np.quantile(d, 0.99) < 0.12
    # the noise-free ranges are the ray caster's from the *laser* pose, not the base pose
    np.testing.assert_allclose(
        r.true_ranges[5], cast_rays(office, r.laser_poses[5], r.angles, 8.0)[0]
    )
    # most beams see something in the office (range_max 8 m), some look down the corridor
    frac_inf = np.isinf(r.ranges).mean()
    assert 0.0 < frac_inf < 0.3


def test_odometry_drift_grows_with_time():
    run = sim.localization_run(duration=40.0)
    err = np.hypot(*(compose(run.true_poses[0], run.odom_poses)[:, :2] - run.true_poses[:, :2]).T)
    n = len(err)
    quarters = [err[i * n // 4 : (i + 1) * n // 4].mean() for i in range(4)]
    assert quarters[0] < quarters[1] < quarters[3]
    assert 0.05 < err[-1] < 3.0


def test_localization_start_is_ambiguous(office):
    # From the start pose, the same pose in the other north offices gives
    # nearly the same scan: global localization is ambiguous at first.
    x, y, th = sim.LOCALIZATION_START
    poses = np.array([[x + dx, y, th] for dx in (-5.0, 0.0, 5.0, 10.0)])
    z = cast_rays(office, compose(poses, (0.1, 0.0, 0.0)), sim.LaserModel().angles, 8.0)
    for k in (0, 2, 3):
        same = np.abs(z[k] - z[1]) < 0.06
        assert same.mean() > 0.85


# -- bags -----------------------------------------------------------------------------
def test_bag_round_trip(tmp_path, short_run):
    r = short_run
    path = sim.write_bag(r, tmp_path / "run.bag")
    assert path.read_bytes()[:13] == b"#ROSBAG V2.0\n"
    with BagReader(path) as bag:
        topics = bag.topics
        assert {n: t.msgtype for n, t in topics.items()} == {
            "/base_scan": "sensor_msgs/msg/LaserScan",
            "/odom": "nav_msgs/msg/Odometry",
            "/ground_truth": "nav_msgs/msg/Odometry",
            "/tf": "tf2_msgs/msg/TFMessage",
        }
        assert {n: v[0] for n, v in sim.BAG_TOPICS.items()} == {
            n: t.msgtype for n, t in topics.items()
        }
        assert topics["/tf"].count == len(r.t) + len(r.scan_t)
        scans = bag.scans("/base_scan")
        odom = bag.odometry("/odom")
        truth = bag.odometry("/ground_truth")
        tf = bag.tf()
    np.testing.assert_array_equal(scans.ranges.astype(np.float32), r.ranges)
    np.testing.assert_allclose(scans.stamps - r.start_time, r.scan_t, atol=1e-6)
    np.testing.assert_allclose(scans.angles, r.angles, atol=1e-6)
    assert scans.range_min == pytest.approx(0.05) and scans.range_max == 8.0  # float32 fields
    assert scans.frame_id == "base_laser_link"
    assert (odom.frame_id, odom.child_frame_id) == ("odom", "base_link")
    np.testing.assert_allclose(odom.stamps - r.start_time, r.t, atol=1e-6)
    np.testing.assert_allclose(odom.poses, r.odom_poses, atol=1e-9)
    assert (truth.frame_id, truth.child_frame_id) == ("map", "base_link")
    np.testing.assert_allclose(truth.stamps - r.start_time, r.scan_t, atol=1e-6)
    np.testing.assert_allclose(truth.poses, r.scan_poses, atol=1e-9)
    np.testing.assert_allclose(
        laser_pose_in_base(tf, "base_laser_link"), r.laser_offset, atol=1e-12
    )
    np.testing.assert_allclose(tf.lookup("odom", "base_link", odom.stamps), r.odom_poses, atol=1e-9)
    assert ("map", "odom") not in tf.edges


def test_bag_bytes_are_deterministic(tmp_path, short_run):
    a = sim.write_bag(short_run, tmp_path / "a.bag").read_bytes()
    b = sim.write_bag(short_run, tmp_path / "b.bag").read_bytes()
    assert hashlib.sha256(a).digest() == hashlib.sha256(b).digest()


def test_write_bag_truth_rate(tmp_path, short_run):
    path = sim.write_bag(short_run, tmp_path / "r.bag", truth_rate=20.0)
    with BagReader(path) as bag:
        assert bag.topics["/ground_truth"].count == len(short_run.t)
    with pytest.raises(ValueError, match="truth_rate"):
        sim.write_bag(short_run, tmp_path / "x.bag", truth_rate=15.0)
    with pytest.raises(TypeError, match="SimRun"):
        sim.write_bag({"t": 1}, tmp_path / "y.bag")


# -- the bundled data -------------------------------------------------------------------
BUNDLED_BAGS = {  # name -> (minimum duration s, route function)
    "mapping.bag": (60.0, sim.mapping_run),
    "localization.bag": (80.0, sim.localization_run),
}


def _bundled(name):
    path = DATA_DIR / name
    assert path.is_file(), f"{path} is missing; run `robolab data`"
    return path


@pytest.mark.parametrize("name", sorted(BUNDLED_BAGS))
def test_bundled_bag_topics_rates_and_duration(name):
    path = _bundled(name)
    assert path.read_bytes()[:12] == b"#ROSBAG V2.0"
    assert path.stat().st_size < 5_000_000
    with BagReader(path) as bag:
        scans = bag.scans("/base_scan")
        odom = bag.odometry("/odom")
        truth = bag.odometry("/ground_truth")
        tf = bag.tf()
        types = {n: t.msgtype for n, t in bag.topics.items()}
    assert types["/base_scan"] == "sensor_msgs/msg/LaserScan"
    assert types["/odom"] == types["/ground_truth"] == "nav_msgs/msg/Odometry"
    assert types["/tf"] == "tf2_msgs/msg/TFMessage"
    assert scans.stamps[-1] - scans.stamps[0] >= BUNDLED_BAGS[name][0]
    assert scans.beams == 360 and scans.range_max == 8.0 and scans.frame_id == "base_laser_link"
    np.testing.assert_allclose(np.diff(scans.stamps), 0.1, atol=1e-6)
    np.testing.assert_allclose(np.diff(odom.stamps), 0.05, atol=1e-6)
    np.testing.assert_allclose(np.diff(truth.stamps), 0.1, atol=1e-6)
    assert scans.stamps[0] == sim.START_TIME
    np.testing.assert_allclose(laser_pose_in_base(tf, scans.frame_id), (0.1, 0.0, 0.0), atol=1e-12)
    assert np.isinf(scans.ranges).any() and (scans.ranges == scans.range_max).any()


@pytest.mark.parametrize("name", sorted(BUNDLED_BAGS))
def test_bundled_bag_regenerates_identically(name):
    # a shorter run of the same seed reproduces the bundled bag's start exactly
    run = BUNDLED_BAGS[name][1](duration=3.0)
    with BagReader(_bundled(name)) as bag:
        scans = bag.scans("/base_scan")
        odom = bag.odometry("/odom")
        truth = bag.odometry("/ground_truth")
    n, k = len(run.scan_t), len(run.t)
    np.testing.assert_array_equal(scans.ranges[:n].astype(np.float32), run.ranges)
    np.testing.assert_allclose(odom.poses[:k], run.odom_poses, atol=1e-9)
    np.testing.assert_allclose(truth.poses[:n], run.scan_poses, atol=1e-9)


def test_bundled_raw_odometry_drifts_visibly():
    with BagReader(_bundled("mapping.bag")) as bag:
        odom = bag.odometry("/odom")
        truth = bag.odometry("/ground_truth")
    t = truth.stamps
    est = compose(truth.poses[0], odom.at(t))
    err = np.hypot(*(est[:, :2] - truth.poses[:, :2]).T)
    assert err[: len(t) // 10].max() < 0.2  # fine at first ...
    assert err.max() > 0.75  # ... smeared later (seed 004, figures 1-2)


def test_make_data_regenerates_small_sets_identically(tmp_path):
    sim.make_data(tmp_path, only=["office", "ekf_world"], progress=False)
    for name in ("office.yaml", "office.pgm", "ekf_world.npz"):
        assert (tmp_path / name).read_bytes() == _bundled(name).read_bytes(), name


def test_the_bundled_graph_regenerates_identically_and_its_optimum_is_near_the_truth(tmp_path):
    """data/graph_slam.g2o (lab 09) is simulate_graph(seed=0); Gauss-Newton recovers the truth."""
    from robolab.datasets import read_g2o
    from robolab.evaluation import absolute_trajectory_error, graph_objective
    from solutions.graph_slam import optimize_graph

    sim.make_data(tmp_path, only=["graph_slam"], progress=False)
    for name in ("graph_slam.g2o", "graph_slam_truth.npz"):
        assert (tmp_path / name).read_bytes() == _bundled(name).read_bytes(), name
    graph = read_g2o(tmp_path / "graph_slam.g2o")
    truth = np.load(tmp_path / "graph_slam_truth.npz")
    assert absolute_trajectory_error(graph.poses, truth["poses"])["rmse"] > 0.5  # the guess drifts
    optimized, _ = optimize_graph(graph)
    assert absolute_trajectory_error(optimized.poses, truth["poses"])["rmse"] < 0.1
    assert np.abs(optimized.landmarks - truth["landmarks"]).max() < 0.5
    # chi-square: F at the optimum is about residuals - free parameters (noise model right)
    dof = 3 * len(graph.edges) + 2 * len(graph.landmark_edges) - (graph.state_size - 3)
    assert abs(graph_objective(optimized) - dof) < 4 * np.sqrt(2 * dof)


def test_make_data_unknown_name_raises(tmp_path):
    with pytest.raises(ValueError, match="valid names: office, mapping, localization, ekf_world"):
        sim.make_data(tmp_path, only=["office", "nope"])
    assert not (tmp_path / "office.yaml").exists()


# -- the EKF world (lab 06) --------------------------------------------------------------
def test_ekf_world_arrays():
    with np.load(_bundled("ekf_world.npz")) as f:
        d = {k: f[k] for k in f.files}
    world, states, scans = d["world"], d["states"], d["scans"]
    s = len(d["speed"])
    assert world.shape == (40, 40) and set(np.unique(world)) == {0.0, 1.0}
    assert states.shape == (s + 1, 3) and scans.shape == d["true_scans"].shape == (s, 36)
    assert d["zmax"] == 20.0 and d["dt"] == 0.1
    np.testing.assert_allclose(np.rad2deg(d["beam_angles"]), 10.0 * np.arange(36))
    np.testing.assert_array_equal(states[0], d["initial_state"])
    # the states follow seed 000's transition model up to the control noise
    x, y, th = states[:-1].T
    pred = np.stack(
        [
            x + d["speed"] * np.cos(th) * 0.1,
            y + d["speed"] * np.sin(th) * 0.1,
            wrap_angle(th + d["rotation_speed"] * 0.1),
        ],
        -1,
    )
    res = states[1:] - pred
    res[:, 2] = wrap_angle(res[:, 2])
    sv, sw = d["control_noise"]
    assert np.abs(res[:, :2]).max() < 5 * sv * 0.1 and np.abs(res[:, 2]).max() < 5 * sw * 0.1
    # the robot stays in free cells and loops around the central block
    grid = OccupancyGrid(world, 1.0)
    rc = grid.world_to_cell(states[:, :2])
    assert grid.free[rc[:, 0], rc[:, 1]].all()
    assert np.ptp(states[:, 0]) > 15 and np.ptp(states[:, 1]) > 15
    # scans: ray cast from the true state after each step, plus noise
    np.testing.assert_allclose(d["true_scans"], cast_rays(grid, states[1:], d["beam_angles"], 20.0))
    assert np.all((scans >= 0) & (scans <= 20.0))
    hit = d["true_scans"] < 20.0
    assert np.std(scans[hit] - d["true_scans"][hit]) == pytest.approx(
        float(d["scan_sigma"]), rel=0.1
    )
    assert np.all(scans[~hit] == 20.0)
