"""Argument checks shared by the library and the reference solutions.

Every public function validates its inputs with these helpers so that bad
input fails early with a message naming the argument and what was expected,
instead of broadcasting silently or returning NaN.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "as_array",
    "as_observations",
    "as_poses",
    "check_count",
    "check_covariance",
    "check_covariance_stack",
    "check_finite",
    "all_finite",
    "check_positive",
    "check_probability_vector",
    "check_rng",
    "LOG_FLOAT_MAX",
]

#: ``log`` of the largest float64: a density whose log exceeds it overflows to inf.
LOG_FLOAT_MAX = float(np.log(np.finfo(float).max))


def _shape_text(shape: Sequence[int | None]) -> str:
    return (
        "("
        + ", ".join("N" if s is None else str(s) for s in shape)
        + ("," if len(shape) == 1 else "")
        + ")"
    )


def as_array(
    name: str,
    value,
    *,
    ndim: int | Sequence[int] | None = None,
    shape: Sequence[int | None] | None = None,
    dtype=float,
    finite: bool = False,
    nonnegative: bool = False,
) -> np.ndarray:
    """Convert ``value`` to an array and check it.

    Parameters
    ----------
    name : str
        The argument's name, used in error messages.
    value : array_like
        What the caller passed.
    ndim : int or sequence of int, optional
        Allowed numbers of dimensions.
    shape : sequence of int or None, optional
        Expected shape; ``None`` entries match any length.
    dtype : numpy dtype, optional
        Target dtype (default float64). Values that cannot be converted raise.
    finite : bool
        Reject NaN and infinity.
    nonnegative : bool
        Reject negative values.

    Returns
    -------
    numpy.ndarray

    Raises
    ------
    TypeError
        When ``value`` cannot be converted to ``dtype``.
    ValueError
        When the shape, dimensionality or values are not as expected.
    """
    if value is None:  # np.asarray(None, float) would silently be NaN
        raise TypeError(f"{name} must be numeric array-like, got None")
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be numeric array-like, got {type(value).__name__}") from exc
    if ndim is not None:
        allowed = (ndim,) if isinstance(ndim, int) else tuple(ndim)
        if arr.ndim not in allowed:
            raise ValueError(
                f"{name} must have {' or '.join(map(str, allowed))} dimension(s), "
                f"got shape {arr.shape}"
            )
    if shape is not None:
        if arr.ndim != len(shape) or any(
            s is not None and s != a for s, a in zip(shape, arr.shape, strict=True)
        ):
            raise ValueError(f"{name} must have shape {_shape_text(shape)}, got {arr.shape}")
    if finite and not all_finite(arr):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    if nonnegative and np.any(arr < 0):
        raise ValueError(f"{name} must be non-negative, got minimum {np.min(arr)}")
    return arr


def as_poses(name: str, value) -> np.ndarray:
    """Return ``value`` as float poses ``(N, 3)``; a single pose ``(3,)`` becomes ``(1, 3)``."""
    arr = as_array(name, value, ndim=(1, 2), finite=True)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.shape[-1] != 3:
        raise ValueError(
            f"{name} must be a pose (x, y, theta) or an (N, 3) array of poses, "
            f"got shape {arr.shape}"
        )
    return arr


def check_positive(name: str, value, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float, raising ValueError unless it is finite and > 0 (or >= 0)."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a number, got {type(value).__name__}") from exc
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(
            f"{name} must be {'>= 0' if allow_zero else '> 0'} and finite, got {value!r}"
        )
    return v


def check_covariance(name: str, value, n: int, *, definite: bool = False) -> np.ndarray:
    """Return ``value`` as an ``(n, n)`` symmetric positive semi-definite (or definite) matrix."""
    c = as_array(name, value, shape=(n, n), finite=True)
    if np.abs(c - c.T).max() > 1e-9 * max(1.0, np.abs(c).max()):
        raise ValueError(f"{name} must be symmetric, got {c.tolist()}")
    eig = np.linalg.eigvalsh(c)
    if eig[0] < -1e-12 * max(1.0, eig[-1]) or (definite and eig[0] <= 0):
        kind = "positive definite" if definite else "positive semi-definite"
        raise ValueError(f"{name} must be {kind}, got eigenvalues {eig.tolist()}")
    return c


def check_covariance_stack(name: str, value, n: int, *, definite: bool = False) -> np.ndarray:
    """Return ``value`` as a stack ``(..., n, n)`` of symmetric PSD (or PD) matrices.

    The vectorized form of :func:`check_covariance`: the message names the first
    bad matrix by its index in the stack.
    """
    c = as_array(name, value, finite=True)
    if c.ndim < 2 or c.shape[-2:] != (n, n):
        raise ValueError(f"{name} must have shape (..., {n}, {n}), got {c.shape}")
    scale = np.maximum(1.0, np.abs(c).max(axis=(-2, -1)))
    asym = np.abs(c - np.swapaxes(c, -1, -2)).max(axis=(-2, -1)) > 1e-9 * scale
    if asym.any():
        k = tuple(int(i) for i in np.argwhere(asym)[0])
        raise ValueError(f"{name}{list(k)} must be symmetric, got {c[k].tolist()}")
    eig = np.linalg.eigvalsh(c)
    bad = eig[..., 0] < -1e-12 * np.maximum(1.0, eig[..., -1])
    if definite:
        bad |= eig[..., 0] <= 0
    if bad.any():
        k = tuple(int(i) for i in np.argwhere(bad)[0])
        kind = "positive definite" if definite else "positive semi-definite"
        raise ValueError(f"{name}{list(k)} must be {kind}, got eigenvalues {eig[k].tolist()}")
    return c


#: From this many entries on, :func:`all_finite` sums first (one pass, no boolean temporary).
SUM_FIRST = 1 << 12


def all_finite(arr: np.ndarray) -> bool:
    """Whether every entry of ``arr`` is finite, as ``np.isfinite(arr).all()``.

    A large float array is summed first: a NaN or infinite entry makes the sum NaN or
    infinite, so a finite sum means finite entries (one pass and no boolean temporary:
    FastSLAM checks its 400 000-entry landmark state every step). A sum that is not
    finite (such an entry, or finite entries whose sum overflows) is settled entry by
    entry.
    """
    if arr.dtype.kind in "fc" and arr.size >= SUM_FIRST:
        with np.errstate(over="ignore", invalid="ignore"):
            if np.isfinite(arr.sum()):
                return True
    return bool(np.isfinite(arr).all())


def check_finite(name: str, value) -> float:
    """Return ``value`` as a float: TypeError unless numeric, ValueError unless finite."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a number, got {type(value).__name__}") from exc
    if not np.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def check_count(name: str, value, *, minimum: int = 1) -> int:
    """Return ``value`` as an int (not a bool) that is at least ``minimum``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def check_rng(rng) -> np.random.Generator:
    """Return ``rng`` if it is a numpy Generator; otherwise TypeError saying how to make one."""
    if not isinstance(rng, np.random.Generator):
        raise TypeError(
            "rng must be a numpy.random.Generator (np.random.default_rng(seed)), "
            f"got {type(rng).__name__}"
        )
    return rng


def check_probability_vector(name: str, value, *, axis: int = -1, atol: float = 1e-9) -> np.ndarray:
    """Return ``value`` as a float array whose entries are in [0, 1] and sum to 1 along ``axis``."""
    arr = as_array(name, value, finite=True)
    if arr.ndim == 0:
        raise ValueError(f"{name} must be a probability vector, got a scalar")
    if np.any(arr < 0):
        raise ValueError(f"{name} must be non-negative, got minimum {arr.min()}")
    sums = arr.sum(axis=axis)
    if not np.allclose(sums, 1.0, atol=atol, rtol=0):
        raise ValueError(f"{name} must sum to 1 along axis {axis}, got {np.ravel(sums)[:3]}")
    return arr


def as_observations(name: str, value, n_landmarks: int) -> np.ndarray:
    """Range-bearing observations with known correspondence as a ``(k, 3)`` float array.

    Rows are ``[range, bearing, id]``: ranges >= 0, ids integers in ``[0, n_landmarks)``,
    everything finite. ``None`` and empty input give an empty ``(0, 3)`` array.
    """
    if value is None:
        return np.empty((0, 3))
    obs = as_array(name, value, finite=True)
    if obs.size == 0:
        return np.empty((0, 3))
    if obs.ndim != 2 or obs.shape[1] != 3:
        raise ValueError(
            f"{name} must have shape (k, 3) rows [range, bearing, id], got {obs.shape}"
        )
    ids = obs[:, 2]
    if np.any(ids != np.round(ids)) or np.any(ids < 0) or np.any(ids >= n_landmarks):
        raise ValueError(
            f"{name}' ids must be integers in [0, {n_landmarks}), got {ids.tolist()}"
        )
    if np.any(obs[:, 0] < 0):
        raise ValueError(f"{name}' ranges must be >= 0, got {obs[:, 0].tolist()}")
    return obs
