"""Hidden tests of the demo lab: 40 points normalize, 30 wrap, 30 mean_pose.

Refusal tests pay only when the function also computes the right values
(``requires``): a function that always raises earns nothing.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

#: CPU seconds the reference solution's worker uses while graded (loading and every call,
#: children included: `cpu_seconds` of the correct example in `make grade`'s gradebook.json,
#: 2026-12-02): a submission gets 8 times that in total, at least 20 s (docs/grading.md).
REFERENCE_CPU_SECONDS = 0.05

# Every demo function takes microseconds: a call that needs seconds is hanging.
GRADING_LIMITS = {"cpu_seconds": 2.0, "wall_seconds": 5.0}


def _floats(result) -> np.ndarray:
    # Compare plain float arrays only: an object with a lying __eq__ earns nothing.
    return np.asarray(result, dtype=float)


def _angle_error(a, b) -> np.ndarray:
    """Distance between angles, insensitive to the 2 pi seam."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    return np.abs(np.arctan2(np.sin(d), np.cos(d)))


@pytest.mark.grades("normalize", points=10)
def test_normalize_sums_to_one(lab):
    """normalize: random positive weights come back as a probability vector of the same length."""
    weights = np.random.default_rng(4).uniform(0.1, 5.0, size=50)
    got = _floats(lab.normalize(weights))
    assert got.shape == (50,), f"expected shape (50,), got {got.shape}"
    assert np.all(got >= 0), f"expected non-negative weights, got minimum {got.min()}"
    assert abs(got.sum() - 1.0) < 1e-9, (
        f"expected the weights to sum to 1, got {float(got.sum())!r}"
    )


@pytest.mark.grades("normalize", points=15)
def test_normalize_known_values(lab):
    """normalize: [1, 1, 2] becomes [0.25, 0.25, 0.5]; a zero weight is valid: [0, 1, 3].

    A single weight is the smallest valid input: [3] becomes [1], still an array (1,).
    """
    one = _floats(lab.normalize(np.array([3.0])))
    assert one.shape == (1,) and one[0] == 1.0, f"normalize([3]): expected [1.0], got {one!r}"
    got = _floats(lab.normalize(np.array([1.0, 1.0, 2.0])))
    np.testing.assert_allclose(
        got,
        [0.25, 0.25, 0.5],
        atol=1e-12,
        err_msg="normalize([1, 1, 2]): expected [0.25, 0.25, 0.5]",
    )
    got = _floats(lab.normalize(np.array([0.0, 1.0, 3.0])))
    np.testing.assert_allclose(
        got,
        [0.0, 0.25, 0.75],
        atol=1e-12,
        err_msg="normalize([0, 1, 3]): a zero weight is allowed, expected [0, 0.25, 0.75]",
    )


REFUSAL_NEEDS = ("test_normalize_sums_to_one", "test_normalize_known_values")


@pytest.mark.grades("normalize", points=7)
@pytest.mark.requires(*REFUSAL_NEEDS)
def test_normalize_rejects_negative_weights(lab, refuses):
    """normalize: a negative weight raises ValueError."""
    with refuses(ValueError, "weights = (0.5, -0.1, 0.6), a negative weight"):
        lab.normalize(np.array([0.5, -0.1, 0.6]))


@pytest.mark.grades("normalize", points=4)
@pytest.mark.requires(*REFUSAL_NEEDS)
def test_normalize_rejects_all_zero(lab, refuses):
    """normalize: all-zero weights raise ValueError instead of dividing by zero."""
    with refuses(ValueError, "weights = four zeros, which cannot be normalized"):
        lab.normalize(np.zeros(4))


@pytest.mark.grades("normalize", points=4)
@pytest.mark.requires(*REFUSAL_NEEDS)
def test_normalize_rejects_2d_input(lab, refuses):
    """normalize: a 2-D array raises ValueError."""
    with refuses(ValueError, "weights of shape (2, 3), not one-dimensional"):
        lab.normalize(np.ones((2, 3)))


@pytest.mark.grades("wrap", points=10)
def test_wrap_known_values(lab):
    """wrap: 3pi/2 -> -pi/2, -3pi/2 -> pi/2, 7 -> 7 - 2pi, 0.5 -> 0.5."""
    for angle, expected in [
        (1.5 * math.pi, -0.5 * math.pi),
        (-1.5 * math.pi, 0.5 * math.pi),
        (7.0, 7.0 - 2 * math.pi),
        (0.5, 0.5),
    ]:
        got = float(_floats(lab.wrap(angle)))
        assert abs(got - expected) < 1e-12, f"wrap({angle!r}): expected {expected!r}, got {got!r}"


@pytest.mark.grades("wrap", points=10)
def test_wrap_half_turn_is_minus_pi(lab):
    """wrap: the interval is [-pi, pi): both pi and -pi wrap to -pi."""
    for angle in (math.pi, -math.pi, 3 * math.pi):
        got = float(_floats(lab.wrap(angle)))
        assert abs(got + math.pi) < 1e-12, f"wrap({angle!r}): expected -pi, got {got!r}"


@pytest.mark.grades("wrap", points=10)
def test_wrap_array(lab):
    """wrap: an array of angles is wrapped elementwise into [-pi, pi) without changing direction."""
    angles = np.linspace(-20.0, 20.0, 101)
    got = _floats(lab.wrap(angles.copy()))
    assert got.shape == angles.shape, f"expected shape {angles.shape}, got {got.shape}"
    assert np.all((got >= -math.pi) & (got < math.pi)), (
        f"expected every angle in [-pi, pi), got range [{got.min()!r}, {got.max()!r}]"
    )
    assert np.all(_angle_error(got, angles) < 1e-9), (
        "wrap(linspace(-20, 20, 101)): expected the same directions as the input angles "
        f"(up to 2 pi), got a largest difference of {float(np.max(_angle_error(got, angles))):.3g}"
    )


@pytest.mark.grades("mean_pose", points=10)
def test_mean_pose_of_aligned_poses(lab):
    """mean_pose: x and y are averaged, equal headings stay as they are."""
    poses = np.array([[0.0, 0.0, 0.3], [2.0, 1.0, 0.3], [4.0, 5.0, 0.3]])
    got = _floats(lab.mean_pose(poses))
    np.testing.assert_allclose(
        got,
        [2.0, 2.0, 0.3],
        atol=1e-12,
        err_msg="mean_pose of three poses heading 0.3 rad: expected [2, 2, 0.3]",
    )


@pytest.mark.grades("mean_pose", points=15)
def test_mean_pose_across_the_seam(lab):
    """mean_pose: headings pi - 0.1 and -pi + 0.1 average to pi (the circular mean), not 0."""
    poses = np.array([[1.0, 0.0, math.pi - 0.1], [3.0, 2.0, -math.pi + 0.1]])
    got = _floats(lab.mean_pose(poses))
    assert got.shape == (3,), f"expected shape (3,), got {got.shape}"
    np.testing.assert_allclose(
        got[:2], [2.0, 1.0], atol=1e-12, err_msg="mean x, y of (1, 0) and (3, 2): expected (2, 1)"
    )
    assert _angle_error(got[2], math.pi) < 1e-9, f"expected heading pi (or -pi), got {got[2]!r}"
    assert -math.pi <= got[2] < math.pi, (
        f"expected the heading wrapped to [-pi, pi), got {got[2]!r}"
    )


@pytest.mark.grades("mean_pose", points=5)
@pytest.mark.requires("test_mean_pose_of_aligned_poses")
def test_mean_pose_rejects_wrong_shape(lab, refuses):
    """mean_pose: poses of shape (N, 2) (no heading), or no poses (0, 3), raise ValueError."""
    with refuses(ValueError, "poses of shape (4, 2), without headings"):
        lab.mean_pose(np.ones((4, 2)))
    with refuses(ValueError, "poses of shape (0, 3): no poses have no mean (not NaN)"):
        lab.mean_pose(np.zeros((0, 3)))
