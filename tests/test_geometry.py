"""robolab.geometry: angle wrapping, pose algebra, point transforms, quaternions."""

from __future__ import annotations

import numpy as np
import pytest

from robolab.geometry import (
    angle_diff,
    compose,
    inverse,
    quaternion_from_yaw,
    relative,
    rotation_matrix,
    transform_points,
    wrap_angle,
    yaw_from_quaternion,
)

PI = np.pi


def _random_poses(n, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-10, 10, (n, 2)), rng.uniform(-PI, PI, n)])


def _same_angle(a, b, atol=1e-9):
    """Angles equal modulo 2 pi (compared on the unit circle)."""
    np.testing.assert_allclose(np.cos(a), np.cos(b), atol=atol)
    np.testing.assert_allclose(np.sin(a), np.sin(b), atol=atol)


# -- wrap_angle -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("angle", "expected"),
    [
        (0.0, 0.0),
        (PI, -PI),
        (-PI, -PI),
        (3 * PI, -PI),
        (-3 * PI, -PI),
        (PI / 2, PI / 2),
        (2 * PI, 0.0),
        (-PI / 2, -PI / 2),
        (1.5 * PI, -PI / 2),
        (-1.5 * PI, PI / 2),
    ],
)
def test_wrap_angle_reference_values(angle, expected):
    assert wrap_angle(angle) == pytest.approx(expected, abs=1e-12)
    assert isinstance(wrap_angle(angle), float)


def test_wrap_angle_pi_maps_to_minus_pi_exactly():
    assert wrap_angle(PI) == -PI
    assert wrap_angle(np.array([PI, -PI]))[0] == -PI


def test_wrap_angle_large_multiples_stay_in_range_and_equivalent():
    k = np.array([1, 2, 3, 10, 101, 1000, 10_001, -7, -1000])
    for offset in (0.0, 0.3, -2.0, PI):
        a = k * 2 * PI + offset
        w = wrap_angle(a)
        assert np.all((w >= -PI) & (w < PI)), w
        _same_angle(w, offset, atol=1e-8)


def test_wrap_angle_random_range_and_idempotent():
    a = np.random.default_rng(3).uniform(-1e4, 1e4, 100_000)
    w = wrap_angle(a)
    assert w.shape == a.shape
    assert np.all((w >= -PI) & (w < PI))
    _same_angle(w, a, atol=1e-9)
    np.testing.assert_array_equal(wrap_angle(w), w)


def test_wrap_angle_is_numpys_remainder_bit_for_bit():
    """Its shortcuts (angles in [-pi, pi), within a turn of it) against the plain formula."""
    rng = np.random.default_rng(5)
    edges = np.array([-PI, PI, 0.0, -0.0, PI / 2, -PI / 2, 2 * PI, -2 * PI, 3 * PI, -3 * PI])
    edges = np.concatenate([edges, np.nextafter(edges, np.inf), np.nextafter(edges, -np.inf)])
    for a in (
        rng.uniform(-PI, PI, 100_000),
        rng.uniform(-3 * PI, 3 * PI, 100_000),
        rng.uniform(-1e4, 1e4, 1000),
        edges,
        edges[np.abs(edges) < PI],
        np.array([]),
    ):
        want = (a + np.pi) % (2.0 * np.pi) - np.pi
        want[want >= np.pi] -= 2.0 * np.pi
        np.testing.assert_array_equal(wrap_angle(a), want)


def test_wrap_angle_just_below_minus_pi_stays_in_range():
    # -pi - 1 ulp: (a + pi) is -4.4e-16 and (a + pi) % 2pi rounds up to exactly 2pi, so a
    # bare `(a + pi) % (2 pi) - pi` returns +pi, outside [-pi, pi).
    a = np.nextafter(-PI, -np.inf)
    w = wrap_angle(a)
    assert -PI <= w < PI
    w_arr = wrap_angle(np.array([a, np.nextafter(PI, np.inf)]))
    assert np.all((w_arr >= -PI) & (w_arr < PI)), w_arr


def test_angle_diff_is_shortest_signed_arc():
    assert angle_diff(0.1, -0.1) == pytest.approx(0.2)
    assert angle_diff(PI - 0.1, -PI + 0.1) == pytest.approx(-0.2)
    assert angle_diff(-PI + 0.1, PI - 0.1) == pytest.approx(0.2)


# -- poses ----------------------------------------------------------------------------------------
def test_compose_hand_computation():
    # Frame a at (1, 2) facing +y; b is 3 m ahead and 1 m to the left in a, turned by 90 deg.
    # In the parent: ahead = +y, left = -x -> (1 - 1, 2 + 3) = (0, 5), heading 180 deg -> -pi.
    np.testing.assert_allclose(
        compose([1.0, 2.0, PI / 2], [3.0, 1.0, PI / 2]), [0.0, 5.0, -PI], atol=1e-12
    )


def test_compose_inverse_identities_on_random_poses():
    p = _random_poses(200)
    q = _random_poses(200, seed=1)
    np.testing.assert_allclose(compose(p, inverse(p)), 0.0, atol=1e-9)
    np.testing.assert_allclose(compose(inverse(p), p), 0.0, atol=1e-9)
    ii = inverse(inverse(p))
    np.testing.assert_allclose(ii[:, :2], p[:, :2], atol=1e-9)
    _same_angle(ii[:, 2], p[:, 2])
    # (p (+) q)^-1 = q^-1 (+) p^-1
    lhs, rhs = inverse(compose(p, q)), compose(inverse(q), inverse(p))
    np.testing.assert_allclose(lhs[:, :2], rhs[:, :2], atol=1e-9)
    _same_angle(lhs[:, 2], rhs[:, 2])


def test_compose_is_associative_and_wraps():
    p, q, r = _random_poses(50), _random_poses(50, 1), _random_poses(50, 2)
    a, b = compose(compose(p, q), r), compose(p, compose(q, r))
    np.testing.assert_allclose(a[:, :2], b[:, :2], atol=1e-9)
    _same_angle(a[:, 2], b[:, 2])
    assert np.all((a[:, 2] >= -PI) & (a[:, 2] < PI))


def test_compose_broadcasts_one_pose_over_many():
    p = _random_poses(10)
    one = np.array([0.5, -1.0, 0.3])
    np.testing.assert_allclose(compose(one, p), np.stack([compose(one, x) for x in p]))


def test_relative_recovers_the_composed_pose():
    a, b = _random_poses(100), _random_poses(100, 5)
    rel = relative(a, b)
    back = compose(a, rel)
    np.testing.assert_allclose(back[:, :2], b[:, :2], atol=1e-9)
    _same_angle(back[:, 2], b[:, 2])
    np.testing.assert_allclose(
        relative([1.0, 1.0, PI / 2], [1.0, 3.0, PI / 2]), [2.0, 0.0, 0.0], atol=1e-12
    )


def test_rotation_matrix_stack():
    r = rotation_matrix(np.array([0.0, PI / 2]))
    assert r.shape == (2, 2, 2)
    np.testing.assert_allclose(r[1], [[0.0, -1.0], [1.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(r[0], np.eye(2))


# -- transform_points -----------------------------------------------------------------------------
def test_transform_points_one_pose_by_hand():
    pts = np.array([[1.0, 0.0], [0.0, 1.0], [2.0, -1.0]])
    out = transform_points(pts, [10.0, 20.0, PI / 2])
    # R(90 deg) (x, y) = (-y, x); plus (10, 20).
    np.testing.assert_allclose(out, [[10.0, 21.0], [9.0, 20.0], [11.0, 22.0]], atol=1e-12)
    assert out.shape == (3, 2)


def test_transform_points_many_poses_match_loop_and_rotation():
    pts = np.random.default_rng(2).normal(size=(7, 2))
    poses = _random_poses(5)
    out = transform_points(pts, poses)
    assert out.shape == (5, 7, 2)
    for k, pose in enumerate(poses):
        expected = pts @ rotation_matrix(pose[2]).T + pose[:2]
        np.testing.assert_allclose(out[k], expected, atol=1e-12)
        np.testing.assert_allclose(out[k], transform_points(pts, pose), atol=1e-12)


def test_transform_points_agrees_with_compose():
    pose = np.array([1.0, -2.0, 0.7])
    pts = np.array([[0.3, 0.4], [-1.0, 2.0]])
    via_compose = compose(pose, np.column_stack([pts, np.zeros(2)]))[:, :2]
    np.testing.assert_allclose(transform_points(pts, pose), via_compose, atol=1e-12)


@pytest.mark.parametrize(
    ("points", "pose", "match"),
    [
        (np.zeros((3, 3)), [0, 0, 0], "points"),
        (np.zeros(2), [0, 0, 0], "points"),
        (np.zeros((3, 2)), [0, 0], "pose"),
        (np.zeros((3, 2)), [0, 0, np.nan], "pose"),
        ("abc", [0, 0, 0], "points"),
    ],
)
def test_transform_points_bad_input(points, pose, match):
    with pytest.raises((ValueError, TypeError), match=match):
        transform_points(points, pose)


# -- quaternions ----------------------------------------------------------------------------------
def test_quaternion_yaw_round_trip():
    yaw = np.linspace(-PI, PI, 1001, endpoint=False)
    q = quaternion_from_yaw(yaw)
    assert q.shape == (1001, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0)
    np.testing.assert_allclose(q[:, :2], 0.0)
    back = yaw_from_quaternion(q[:, 0], q[:, 1], q[:, 2], q[:, 3])
    np.testing.assert_allclose(back, yaw, atol=1e-12)


def test_quaternion_reference_values():
    np.testing.assert_allclose(quaternion_from_yaw(PI / 2), [0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5)])
    assert yaw_from_quaternion(0.0, 0.0, 0.0, 1.0) == 0.0
    # q and -q are the same rotation
    assert yaw_from_quaternion(0.0, 0.0, -np.sqrt(0.5), -np.sqrt(0.5)) == pytest.approx(PI / 2)


def test_yaw_from_quaternion_is_wrapped_to_half_open_range():
    # The half-turn quaternion (0, 0, 1, ~6e-17) gives atan2(+tiny, -1) = +pi; the project's
    # convention is [-pi, pi), so the yaw must be -pi (as wrap_angle(pi)).
    x, y, z, w = quaternion_from_yaw(PI)
    assert yaw_from_quaternion(x, y, z, w) == -PI
