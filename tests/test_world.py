"""Tests for robolab.world: the cyclic landmark world of seed 002.

Stochastic tests fix their seeds; moment bounds are 5 standard errors computed
from the number of samples (a correct model fails one with probability < 1e-6).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest
from scipy.stats import norm

from robolab.world import LANDMARKS, cRobot, cWorld, landmark_ranges, wrap_position

SEED_PATH = np.array(
    [[0.0, 60.0], [np.pi / 3, 30.0], [np.pi / 4, 30.0], [np.pi / 4, 20.0], [np.pi / 4, 40.0]]
)


def robot(seed=0, pose=(50.0, 50.0, 0.0), noise=(0.0, 0.0, 0.0)):
    r = cRobot(rng=np.random.default_rng(seed))
    r.set_noise(*noise)
    r.set(*pose)
    return r


# ---------------------------------------- cWorld


def test_world_defaults_are_the_classic_landmarks():
    w = cWorld()
    assert w.size == 100.0
    np.testing.assert_array_equal(w.landmarks, [[20, 20], [80, 80], [20, 80], [80, 20]])
    w.landmarks[0, 0] = -1.0
    assert LANDMARKS[0, 0] == 20.0, "a world must own a copy of the landmarks"


@pytest.mark.parametrize(
    "landmarks, size, exc, words",
    [
        (np.zeros((3, 3)), 100, ValueError, "landmarks"),
        (np.zeros((0, 2)), 100, ValueError, "landmarks"),
        ([[10, 10], [100, 5]], 100, ValueError, "landmarks"),
        ([[10, np.nan]], 100, ValueError, "landmarks"),
        ([["a", "b"]], 100, TypeError, "landmarks"),
        (None, 0, ValueError, "size"),
        (None, -5, ValueError, "size"),
    ],
)
def test_world_rejects_bad_input(landmarks, size, exc, words):
    with pytest.raises(exc, match=words):
        cWorld(landmarks, size=size)


def test_world_plot_draws_landmarks_with_labels():
    ax = cWorld().plot()
    np.testing.assert_array_equal(ax.collections[0].get_offsets(), LANDMARKS)
    assert ax.get_xlabel() and ax.get_ylabel() and ax.get_title()
    assert ax.get_xlim() == (0.0, 100.0)
    plt.close(ax.figure)


# ---------------------------------------- set / set_noise


@pytest.mark.parametrize(
    "x, y", [(100.0, 5.0), (5.0, 100.0), (-0.1, 5.0), (5.0, -1e-9), (150.0, 150.0)]
)
def test_set_rejects_positions_outside_the_world(x, y):
    r = cRobot(rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"\[0, 100\)"):
        r.set(x, y, 0.0)


def test_set_rejects_non_numbers_and_non_finite():
    r = cRobot(rng=np.random.default_rng(0))
    with pytest.raises(TypeError, match="x"):
        r.set("ten", 5, 0)
    with pytest.raises(ValueError, match="theta"):
        r.set(5, 5, np.inf)
    with pytest.raises(ValueError, match="y"):
        r.set(5, np.nan, 0)


def test_set_accepts_the_corners_and_wraps_heading():
    r = cRobot(rng=np.random.default_rng(0))
    r.set(0.0, 99.999, 3 * np.pi / 2)
    assert (r.x, r.y) == (0.0, 99.999)
    assert r.theta == pytest.approx(-np.pi / 2)
    r.set(1.0, 1.0, np.pi)
    assert r.theta == pytest.approx(-np.pi)  # [-pi, pi): pi maps to -pi


def test_set_noise_rejects_negative_values():
    r = cRobot(rng=np.random.default_rng(0))
    for args, name in (
        ((-1, 0, 0), "forward_noise"),
        ((0, -1, 0), "turn_noise"),
        ((0, 0, np.nan), "sense_noise"),
    ):
        with pytest.raises(ValueError, match=name):
            r.set_noise(*args)


def test_constructor_pose_is_inside_the_world_and_rng_is_checked():
    for seed in range(20):
        r = cRobot(rng=np.random.default_rng(seed))
        assert 0 <= r.x < 100 and 0 <= r.y < 100 and -np.pi <= r.theta < np.pi
    with pytest.raises(TypeError, match="rng"):
        cRobot(rng=42)


# ---------------------------------------- move


def test_noise_free_moves_follow_the_seed_path_exactly():
    r = robot(pose=(10.0, 15.0, 0.0))
    heading, pos = 0.0, np.array([10.0, 15.0])
    for ur, ut in SEED_PATH:
        r.move(ur, ut)
        heading += ur
        pos = pos + ut * np.array([np.cos(heading), np.sin(heading)])
        np.testing.assert_allclose([r.x, r.y], pos, atol=1e-9)
        assert r.theta == pytest.approx(heading if heading < np.pi else heading - 2 * np.pi)
    np.testing.assert_allclose(pos, [21.278, 69.606], atol=1e-3)  # the seed's intended end point


@pytest.mark.parametrize(
    "pose, u, expected",
    [
        ((99.0, 50.0, 0.0), (0.0, 2.0), (1.0, 50.0)),
        ((1.0, 50.0, np.pi), (0.0, 2.0), (99.0, 50.0)),
        ((50.0, 99.5, 0.0), (np.pi / 2, 1.0), (50.0, 0.5)),
        ((50.0, 0.5, 0.0), (-np.pi / 2, 1.0), (50.0, 99.5)),
        ((10.0, 10.0, 0.0), (0.0, 250.0), (60.0, 10.0)),  # more than one lap
        ((10.0, 10.0, 0.0), (0.0, -30.0), (80.0, 10.0)),  # backwards
    ],
)
def test_moves_wrap_at_the_edges(pose, u, expected):
    r = robot(pose=pose).move(*u)
    np.testing.assert_allclose([r.x, r.y], expected, atol=1e-9)
    assert 0 <= r.x < 100 and 0 <= r.y < 100


def test_wrap_position_never_returns_size():
    assert wrap_position(-1e-17) == 0.0  # np.mod(-1e-17, 100) is 100.0
    np.testing.assert_allclose(wrap_position([-5.0, 100.0, 205.0, 3.0]), [95.0, 0.0, 5.0, 3.0])
    assert wrap_position(12.5, size=10) == 2.5
    with pytest.raises(ValueError, match="size"):
        wrap_position(1.0, size=0)


def test_heading_stays_wrapped_over_many_noisy_turns():
    r = robot(seed=1, noise=(1.0, 0.5, 0.0))
    for _ in range(500):
        r.move(1.3, 2.0)
        assert -np.pi <= r.theta < np.pi
        assert 0 <= r.x < 100 and 0 <= r.y < 100


def test_one_forward_noise_sample_moves_along_the_heading():
    # The seed draws two forward-noise samples (x and y): its robot leaves its heading.
    # With turn_noise 0 the displacement must be parallel to (cos theta, sin theta).
    r = robot(seed=2, pose=(50.0, 50.0, 0.7), noise=(5.0, 0.0, 0.0))
    for _ in range(200):
        r.set(50.0, 50.0, 0.7)
        r.move(0.0, 10.0)
        dx, dy = r.x - 50.0, r.y - 50.0
        assert abs(dx * np.sin(0.7) - dy * np.cos(0.7)) < 1e-9


def test_move_moments_match_the_model():
    # 4000 one-step moves from the same pose: theta ~ N(th0 + u_rot, s_t^2); with turn
    # noise 0, dx ~ N(u cos th, s_f^2 cos^2 th). Bounds: 5 standard errors.
    n, s_t, s_f = 4000, 0.2, 3.0
    r = robot(seed=3, noise=(0.0, s_t, 0.0))
    th = np.empty(n)
    for i in range(n):
        r.set(50.0, 50.0, 0.1)
        th[i] = r.move(0.4, 0.0).theta
    assert abs(th.mean() - 0.5) < 5 * s_t / np.sqrt(n)
    assert abs(th.var(ddof=1) - s_t**2) < 5 * s_t**2 * np.sqrt(2 / (n - 1))
    r = robot(seed=4, noise=(s_f, 0.0, 0.0))
    dx = np.empty(n)
    for i in range(n):
        r.set(50.0, 50.0, 0.5)
        dx[i] = r.move(0.0, 10.0).x - 50.0
    sd = s_f * np.cos(0.5)
    assert abs(dx.mean() - 10 * np.cos(0.5)) < 5 * sd / np.sqrt(n)
    assert abs(dx.var(ddof=1) - sd**2) < 5 * sd**2 * np.sqrt(2 / (n - 1))


def test_move_rejects_non_finite_commands():
    r = robot()
    with pytest.raises(ValueError, match="u_translation"):
        r.move(0.0, np.nan)
    with pytest.raises(TypeError, match="u_rotation"):
        r.move("left", 1.0)


def test_same_seed_same_trajectory():
    a, b = robot(seed=7, noise=(2, 0.1, 1)), robot(seed=7, noise=(2, 0.1, 1))
    for ur, ut in SEED_PATH:
        np.testing.assert_array_equal(a.move(ur, ut).pose, b.move(ur, ut).pose)
        np.testing.assert_array_equal(a.sense(cWorld()), b.sense(cWorld()))


# ---------------------------------------- sense / measurement_probability


def test_noise_free_sense_is_the_plain_euclidean_range():
    r = robot(pose=(95.0, 20.0, 0.0))
    z = r.sense(cWorld())
    # no cyclic wrap in the range (as in the seed): (20, 20) is 75 away, not 25
    np.testing.assert_allclose(z, [75.0, np.hypot(15, 60), np.hypot(75, 60), 15.0])
    np.testing.assert_allclose(landmark_ranges([[95.0, 20.0]], LANDMARKS), [z])


def test_sense_distribution_moments():
    # 20000 readings at a fixed pose: each range ~ N(true, s^2), independent across landmarks.
    n, s = 20000, 5.0
    r = robot(seed=5, pose=(40.0, 30.0, 1.0), noise=(0.0, 0.0, s))
    w = cWorld()
    z = np.array([r.sense(w) for _ in range(n)])
    true = np.hypot(40.0 - LANDMARKS[:, 0], 30.0 - LANDMARKS[:, 1])
    np.testing.assert_array_less(np.abs(z.mean(0) - true), 5 * s / np.sqrt(n))
    np.testing.assert_array_less(np.abs(z.var(0, ddof=1) - s**2), 5 * s**2 * np.sqrt(2 / (n - 1)))
    corr = np.corrcoef(z.T)[np.triu_indices(4, 1)]
    np.testing.assert_array_less(
        np.abs(corr), 5 / np.sqrt(n)
    )  # SE of a zero correlation ~ 1/sqrt(n)


def test_sense_requires_a_world():
    with pytest.raises(TypeError, match="world"):
        robot().sense(LANDMARKS)


def test_measurement_probability_is_the_product_of_normal_densities():
    rng = np.random.default_rng(6)
    w = cWorld()
    for _ in range(10):
        r = robot(pose=(*rng.uniform(0, 100, 2), 0.0), noise=(0, 0, 4.0))
        z = rng.uniform(0, 120, 4)
        true = np.hypot(r.x - LANDMARKS[:, 0], r.y - LANDMARKS[:, 1])
        assert r.measurement_probability(z, w) == pytest.approx(
            np.prod(norm.pdf(z, true, 4.0)), rel=1e-10
        )


def test_measurement_probability_bad_input():
    r = robot(noise=(0, 0, 0))
    with pytest.raises(ValueError, match="sense_noise"):
        r.measurement_probability(np.zeros(4), cWorld())
    r.set_noise(0, 0, 1)
    with pytest.raises(ValueError, match="measured"):
        r.measurement_probability(np.zeros(3), cWorld())


def test_robot_plot_draws_position_and_heading():
    r = robot(pose=(40.0, 40.0, np.pi / 2))
    ax = cWorld().plot()
    r.plot(ax, label="robot 1")
    lines = ax.get_lines()
    np.testing.assert_allclose(np.column_stack(lines[0].get_data()), [[40.0, 40.0]])
    heading = np.column_stack(lines[1].get_data())
    np.testing.assert_allclose(heading[1] - heading[0], [0.0, 6.0], atol=1e-9)
    plt.close(ax.figure)
