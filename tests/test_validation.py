"""robolab.validation: bad input fails early with a message naming the argument."""

from __future__ import annotations

import numpy as np
import pytest

from robolab.validation import (
    SUM_FIRST,
    all_finite,
    as_array,
    as_poses,
    check_positive,
    check_probability_vector,
)


# -- as_array ------------------------------------------------------------------------------
def test_as_array_converts_to_float_and_keeps_values():
    out = as_array("x", [1, 2, 3])
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, [1.0, 2.0, 3.0])
    assert as_array("n", [1, 2], dtype=np.int64).dtype == np.int64


def test_as_array_accepts_matching_shape_with_wildcards():
    assert as_array("pts", np.zeros((5, 2)), shape=(None, 2)).shape == (5, 2)
    assert as_array("v", np.zeros(3), ndim=(1, 2)).shape == (3,)


@pytest.mark.parametrize(
    ("value", "kwargs", "message"),
    [
        (np.zeros((2, 2)), {"ndim": 1}, r"x must have 1 dimension\(s\), got shape \(2, 2\)"),
        (np.zeros(3), {"ndim": (2, 3)}, r"x must have 2 or 3 dimension"),
        (np.zeros((5, 3)), {"shape": (None, 2)}, r"x must have shape \(N, 2\), got \(5, 3\)"),
        (np.zeros(4), {"shape": (3,)}, r"x must have shape \(3,\), got \(4,\)"),
        (np.zeros((3, 1)), {"shape": (3,)}, r"x must have shape \(3,\)"),
        ([1.0, np.nan], {"finite": True}, r"x must be finite"),
        ([1.0, np.inf], {"finite": True}, r"x must be finite"),
        ([1.0, -0.5], {"nonnegative": True}, r"x must be non-negative, got minimum -0.5"),
    ],
)
def test_as_array_rejects_with_named_message(value, kwargs, message):
    with pytest.raises(ValueError, match=message):
        as_array("x", value, **kwargs)


@pytest.mark.parametrize("value", ["abc", {"a": 1}, [[1, 2], [3]], object(), 1 + 2j])
def test_as_array_non_numeric_is_type_error(value):
    with pytest.raises(TypeError, match=r"^x must be numeric array-like"):
        as_array("x", value)


def test_as_array_none_is_type_error_not_nan():
    # np.asarray(None, dtype=float) is array(nan): without an explicit check a missing
    # argument would flow on as NaN, which is what validation exists to prevent.
    with pytest.raises(TypeError, match="x"):
        as_array("x", None)


def test_as_array_finite_and_nonnegative_accept_good_values():
    np.testing.assert_array_equal(
        as_array("x", [0.0, 2.0], finite=True, nonnegative=True), [0.0, 2.0]
    )


# -- as_poses ------------------------------------------------------------------------------------
def test_as_poses_single_and_many():
    assert as_poses("pose", [1, 2, 3]).shape == (1, 3)
    assert as_poses("poses", np.zeros((4, 3))).shape == (4, 3)


@pytest.mark.parametrize(
    ("value", "match"),
    [
        (np.zeros((4, 2)), r"poses must be a pose \(x, y, theta\) or an \(N, 3\) array"),
        ([1.0, 2.0], r"poses must be a pose"),
        (np.zeros((2, 3, 3)), r"poses must have 1 or 2 dimension"),
        ([0.0, 0.0, np.inf], r"poses must be finite"),
    ],
)
def test_as_poses_rejects(value, match):
    with pytest.raises(ValueError, match=match):
        as_poses("poses", value)


# -- check_positive -----------------------------------------------------------------------------
def test_check_positive_returns_float():
    v = check_positive("resolution", np.float32(0.05))
    assert type(v) is float and v == pytest.approx(0.05)
    assert check_positive("r", 0, allow_zero=True) == 0.0


@pytest.mark.parametrize("value", [0, -1.0, np.nan, np.inf, -np.inf])
def test_check_positive_rejects_non_positive(value):
    with pytest.raises(ValueError, match=r"^resolution must be > 0 and finite"):
        check_positive("resolution", value)


def test_check_positive_allow_zero_message():
    with pytest.raises(ValueError, match=r"r must be >= 0"):
        check_positive("r", -1e-9, allow_zero=True)


@pytest.mark.parametrize("value", [None, "abc", [1.0, 2.0]])
def test_check_positive_non_number_is_type_error(value):
    with pytest.raises(TypeError, match=r"^resolution must be a number"):
        check_positive("resolution", value)


# -- check_probability_vector ---------------------------------------------------------------------
def test_check_probability_vector_accepts_and_returns_float():
    out = check_probability_vector("prior", [0.25, 0.75])
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, [0.25, 0.75])
    m = np.array([[1.0, 0.8], [0.0, 0.2]])  # columns sum to 1
    np.testing.assert_array_equal(check_probability_vector("A", m, axis=0), m)
    # rounding error well below the tolerance is fine
    check_probability_vector("p", np.full(10, 0.1))


@pytest.mark.parametrize(
    ("value", "kwargs", "match"),
    [
        ([0.5, 0.6], {}, r"prior must sum to 1 along axis -1"),
        ([1.2, -0.2], {}, r"prior must be non-negative"),
        (0.5, {}, r"prior must be a probability vector, got a scalar"),
        ([0.5, np.nan], {}, r"prior must be finite"),
        ([], {}, r"prior must sum to 1"),
        ([[1.0, 0.8], [0.0, 0.2]], {"axis": -1}, r"prior must sum to 1 along axis -1"),
    ],
)
def test_check_probability_vector_rejects(value, kwargs, match):
    with pytest.raises(ValueError, match=match):
        check_probability_vector("prior", value, **kwargs)


@pytest.mark.parametrize("dtype", [np.float64, np.float32, np.complex128])
@pytest.mark.parametrize("size", [0, 1, SUM_FIRST - 1, SUM_FIRST, 3 * SUM_FIRST + 7])
def test_all_finite_agrees_with_isfinite_all(dtype, size):
    """The sum-first shortcut answers as ``np.isfinite(a).all()``: a NaN or +-inf anywhere,
    +inf and -inf together (a NaN sum), and finite entries whose sum overflows."""
    rng = np.random.default_rng(size)
    big = np.finfo(np.dtype(dtype).type(0).real.dtype).max
    for bad in (None, np.nan, np.inf, -np.inf, "both", "overflow"):
        a = rng.standard_normal(size).astype(dtype)
        if size and bad == "both":
            a[0], a[-1] = np.inf, -np.inf
        elif size and bad == "overflow":
            a[:] = big
        elif size and bad is not None:
            a[rng.integers(size)] = bad
        assert all_finite(a) == bool(np.isfinite(a).all())
        assert all_finite(a.reshape(-1, 1)[::-1]) == bool(np.isfinite(a).all())
