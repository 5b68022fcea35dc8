"""Tests of robolab.fiducials, the fiducial robot of lab 07 (seed 003's Robot.m).

Stochastic tests fix the seed; moment tolerances are 5 standard errors computed
from the number of samples (a correct simulator fails them with probability
< 1e-6), while a wrong noise scale (e.g. standard deviation used as variance)
misses them by far more.
"""

from __future__ import annotations

import numpy as np
import pytest

from robolab import fiducials as fd
from robolab.fiducials import FiducialRobot, FiducialRun, load_run, write_run
from robolab.geometry import transform_points, wrap_angle


def _replay(robot):
    """Everything the Robot.m interface hands out, step by step."""
    steps = []
    while robot.run():
        steps.append((robot.input(), robot.measurement()))
    return steps


def _true_range_bearing(fiducials, pose):
    d = fiducials - pose[:2]
    return np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0]) - pose[2]


# -- the interface ---------------------------------------------------------------


def test_defaults_follow_the_seed():
    robot = FiducialRobot()
    np.testing.assert_array_equal(robot.x0, [-2.5, -2.0, 0.25])
    np.testing.assert_array_equal(robot.true_poses[0], [-2.5, -2.0, 0.25])
    assert robot.fiducials.shape == (5, 2)
    np.testing.assert_array_equal(robot.fiducials, fd.FIDUCIALS)
    assert robot.n_fiducials == 5


def test_run_returns_true_exactly_n_steps_times_then_false():
    robot = FiducialRobot(seed=3, n_steps=7)
    results = [robot.run() for _ in range(9)]
    assert results == [True] * 7 + [False, False]
    assert robot.step == 7


def test_input_and_measurement_before_run_raise():
    robot = FiducialRobot(n_steps=3)
    with pytest.raises(RuntimeError, match="run"):
        robot.input()
    with pytest.raises(RuntimeError, match="run"):
        robot.measurement()


def test_input_is_the_route_command_and_a_copy():
    robot = FiducialRobot(seed=0, n_steps=50)
    for t in range(50):
        robot.run()
        u = robot.input()
        w0 = 2 * np.pi / 20
        np.testing.assert_allclose(
            u, [1.0, w0 * (1 + np.cos(3 * w0 * t * 0.1))], rtol=0, atol=1e-12
        )
        u[:] = 99.0  # mutating what was handed out must not change the robot
        np.testing.assert_array_equal(robot.input(), fd.route_command(t * 0.1))


def test_measurement_rows_are_range_bearing_id_with_wrapped_bearings():
    robot = FiducialRobot(seed=1)
    seen = set()
    for _, z in _replay(robot):
        assert z.ndim == 2 and z.shape[1] == 3
        assert np.all((z[:, 1] >= -np.pi) & (z[:, 1] < np.pi))
        assert np.all(z[:, 2] == np.round(z[:, 2]))
        seen.update(z[:, 2].astype(int).tolist())
    assert seen == set(range(5)), "the route must show every fiducial"


# -- determinism -----------------------------------------------------------------


def test_same_seed_same_run_and_different_seed_different_run():
    a, b, c = (
        FiducialRobot(seed=5, n_steps=300),
        FiducialRobot(seed=5, n_steps=300),
        FiducialRobot(seed=6, n_steps=300),
    )
    np.testing.assert_array_equal(a.true_poses, b.true_poses)
    sa, sb = _replay(a), _replay(b)
    for (ua, za), (ub, zb) in zip(sa, sb, strict=True):
        np.testing.assert_array_equal(ua, ub)
        np.testing.assert_array_equal(za, zb)
    assert not np.allclose(a.true_poses, c.true_poses)


def test_measurement_is_repeatable_within_a_step():
    robot = FiducialRobot(seed=2, n_steps=40)
    for _ in range(40):
        robot.run()
        np.testing.assert_array_equal(robot.measurement(), robot.measurement())


# -- motion model ----------------------------------------------------------------


def test_unicycle_without_noise_is_exact():
    robot = FiducialRobot(seed=0, n_steps=400, Q=np.zeros((3, 3)))
    p, dt = robot.true_poses, robot.dt
    for t in range(400):
        robot.run()
        v, w = robot.input()
        expected = [
            p[t, 0] + v * dt * np.cos(p[t, 2]),
            p[t, 1] + v * dt * np.sin(p[t, 2]),
            wrap_angle(p[t, 2] + w * dt),
        ]
        np.testing.assert_allclose(p[t + 1], expected, rtol=0, atol=1e-12)
        assert -np.pi <= p[t + 1, 2] < np.pi


def test_noise_free_route_closes_its_loop_every_20_seconds():
    robot = FiducialRobot(n_steps=200, Q=np.zeros((3, 3)))
    end = robot.true_poses[-1]
    # Euler integration of a closed curve: heading exactly 2 pi, position within 5 cm
    assert abs(wrap_angle(end[2] - robot.x0[2])) < 1e-9
    assert np.hypot(*(end[:2] - robot.x0[:2])) < 0.05
    extent = np.ptp(robot.true_poses[:, :2], axis=0)
    assert np.all(extent > 5.0), f"the loop should span metres, got {extent}"


def test_process_noise_statistics_match_Q():
    Q = np.array([[4e-4, 1e-4, 0.0], [1e-4, 2e-4, 0.0], [0.0, 0.0, 1e-4]])
    n = 20000
    robot = FiducialRobot(seed=4, n_steps=n, Q=Q, max_range=0.6)
    p = robot.true_poses
    u = fd.route_command(np.arange(n) * robot.dt)
    pred = fd.unicycle(p[:-1], u, robot.dt)
    w = p[1:] - pred
    w[:, 2] = wrap_angle(w[:, 2])
    cov = np.cov(w.T)
    # SE of a sample covariance entry: sqrt((S_ii S_jj + S_ij^2) / n)
    se = np.sqrt((np.outer(np.diag(Q), np.diag(Q)) + Q**2) / n)
    assert np.all(np.abs(cov - Q) < 5 * se), f"noise covariance {cov} differs from Q {Q}"
    assert np.all(np.abs(w.mean(0)) < 5 * np.sqrt(np.diag(Q) / n))


# -- measurement model ------------------------------------------------------------


def test_measurement_noise_statistics_match_Qt():
    Qt = np.diag([0.05**2, 0.02**2])
    robot = FiducialRobot(seed=7, n_steps=4000, Qt=Qt)
    res = []
    while robot.run():
        z = robot.measurement()
        r, b = _true_range_bearing(robot.fiducials[z[:, 2].astype(int)], robot.pose)
        res.append(np.column_stack([z[:, 0] - r, wrap_angle(z[:, 1] - b)]))
    res = np.vstack(res)
    n = len(res)
    assert n > 3000
    cov = np.cov(res.T)
    se = np.sqrt((np.outer(np.diag(Qt), np.diag(Qt)) + Qt**2) / n)
    assert np.all(np.abs(cov - Qt) < 5 * se), (
        f"measurement noise covariance {cov} differs from Qt {Qt}"
    )
    assert np.all(np.abs(res.mean(0)) < 5 * np.sqrt(np.diag(Qt) / n))


def test_field_of_view_and_range_filter():
    # five fiducials placed relative to the pose after the first (noise-free) step
    robot0 = FiducialRobot(n_steps=1, Q=np.zeros((3, 3)))
    pose = robot0.true_poses[1]
    local = np.array(
        [
            [3.0, 0.0],  # 0: ahead, 3 m: seen
            [-3.0, 0.0],  # 1: behind: outside the 90 degree view
            [3.0 * np.cos(0.7), 3.0 * np.sin(0.7)],  # 2: 40 degrees left: seen
            [3.0 * np.cos(0.87), -3.0 * np.sin(0.87)],  # 3: 50 degrees right: outside +-45 degrees
            [6.0, 0.0],  # 4: beyond max_range = 5 m
            [0.3, 0.0],  # 5: closer than min_range = 0.5 m
        ]
    )
    world = transform_points(local, pose)
    robot = FiducialRobot(
        n_steps=1,
        Q=np.zeros((3, 3)),
        Qt=np.zeros((2, 2)),
        fov=np.pi / 2,
        max_range=5.0,
        min_range=0.5,
        fiducials=world,
    )
    robot.run()
    z = robot.measurement()
    np.testing.assert_array_equal(z[:, 2], [0, 2])
    np.testing.assert_allclose(z[:, 0], [3.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(z[:, 1], [0.0, 0.7], atol=1e-12)
    # a full circle of view sees the one behind too, with bearing -pi (wrapped from +pi)
    robot = FiducialRobot(
        n_steps=1, Q=np.zeros((3, 3)), Qt=np.zeros((2, 2)), fov=2 * np.pi, fiducials=world
    )
    robot.run()
    z = robot.measurement()
    np.testing.assert_array_equal(z[:, 2], [0, 1, 2, 3])
    np.testing.assert_allclose(abs(z[1, 1]), np.pi, atol=1e-9)


def test_more_fiducials_for_the_benchmark():
    lay = fd.fiducial_layout(15)
    assert lay.shape == (15, 2)
    np.testing.assert_array_equal(lay[:5], fd.FIDUCIALS)
    d = np.hypot(*(lay[:, None] - lay[None]).transpose(2, 0, 1))
    assert d[np.triu_indices(15, 1)].min() > 1.0, "fiducials must be distinguishable on a plot"
    robot = FiducialRobot(n_fiducials=15)
    ids = np.concatenate([z[:, 2] for _, z in _replay(robot)]).astype(int)
    assert set(ids.tolist()) == set(range(15))


# -- recorded runs ---------------------------------------------------------------


def test_write_load_round_trip(tmp_path):
    path = write_run(tmp_path / "sub" / "fastslam.npz", seed=11, n_steps=250)
    assert path == tmp_path / "sub" / "fastslam.npz" and path.is_file()
    run = load_run(path)
    robot = FiducialRobot(seed=11, n_steps=250)
    assert isinstance(run, FiducialRun)
    assert run.n_steps == 250 and run.n_fiducials == 5
    np.testing.assert_array_equal(run.true_poses, robot.true_poses)
    np.testing.assert_array_equal(run.fiducials, robot.fiducials)
    np.testing.assert_array_equal(run.Q, robot.Q)
    np.testing.assert_array_equal(run.Qt, robot.Qt)
    np.testing.assert_array_equal(run.x0, robot.x0)
    assert run.dt == robot.dt
    assert run.commands.shape == (250, 2) and run.measurements.shape[1] == 4
    # the replay hands out exactly what the live robot does
    for (ua, za), (ub, zb) in zip(_replay(run.robot()), _replay(robot), strict=True):
        np.testing.assert_array_equal(ua, ub)
        np.testing.assert_array_equal(za, zb)
    for t in (0, 17, 249):
        np.testing.assert_array_equal(
            run.observations(t), run.measurements[run.measurements[:, 0] == t, 1:]
        )


def test_as_robot_accepts_robot_run_and_path(tmp_path):
    robot = FiducialRobot(n_steps=5)
    assert fd.as_robot(robot) is robot
    run = robot.to_run()
    path = run.save(tmp_path / "r.npz")
    for source in (run, path, str(path)):
        replay = fd.as_robot(source)
        assert isinstance(replay, FiducialRobot) and replay.step == 0
        np.testing.assert_array_equal(replay.true_poses, robot.true_poses)
    with pytest.raises(TypeError, match="robot_or_run"):
        fd.as_robot(42)


def test_load_run_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        load_run(tmp_path / "missing.npz")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match="bad.npz"):
        load_run(bad)
    partial = tmp_path / "partial.npz"
    np.savez(partial, commands=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="missing measurements"):
        load_run(partial)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"dt": -0.1}, "dt"),
        ({"Q": np.eye(2)}, "Q"),
        ({"Q": -np.eye(3)}, "Q"),
        ({"Qt": [[1.0, 2.0], [0.0, 1.0]]}, "Qt"),
        ({"fov": 7.0}, "fov"),
        ({"max_range": 0.0}, "max_range"),
        ({"min_range": 6.0}, "min_range"),
        ({"n_steps": 0}, "n_steps"),
        ({"n_fiducials": 0}, "n_fiducials"),
        ({"fiducials": np.zeros((3, 3))}, "fiducials"),
        ({"x0": [0.0, 0.0]}, "x0"),
    ],
)
def test_bad_arguments_name_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        FiducialRobot(**kwargs)


def test_seed_must_be_an_int():
    with pytest.raises(TypeError, match="seed"):
        FiducialRobot(seed=1.5)
