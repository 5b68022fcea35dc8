"""The demo lab: three small exercises that exist to test the autograder itself.

They are deliberately tiny but follow every rule of a real lab: validated input
with errors naming the argument, vectorized numpy, angles wrapped by the one
helper in :mod:`robolab.geometry`.
"""

from __future__ import annotations

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array

#: Number of columns of a pose array: x, y, theta.
POSE_WIDTH = 3


def _circular_mean(angles: np.ndarray) -> float:
    """Mean direction of ``angles``: the angle of the mean unit vector, wrapped to [-pi, pi)."""
    return wrap_angle(np.arctan2(np.mean(np.sin(angles)), np.mean(np.cos(angles))))


def normalize(weights) -> np.ndarray:
    """Scale non-negative weights so that they sum to one.

    Parameters
    ----------
    weights : array_like, shape (N,)
        Non-negative importance weights, not all zero.

    Returns
    -------
    numpy.ndarray, shape (N,)
        ``weights / sum(weights)`` as floats.

    Raises
    ------
    ValueError
        When ``weights`` is not 1-D, is empty, has a negative or non-finite
        entry, or sums to zero.
    """
    w = as_array("weights", weights, ndim=1, finite=True, nonnegative=True)
    if w.size and w.max() > 0:
        w = w / w.max()  # the same ratios; the sum of weights near 1e308 cannot overflow
    total = w.sum()
    if w.size == 0 or total <= 0.0:
        raise ValueError(
            f"weights must contain a positive entry, got {w.size} weights summing to {total}"
        )
    return w / total


def wrap(angle):
    """Wrap an angle (or an array of angles) to ``[-pi, pi)``; ``wrap(pi) == -pi``.

    Written out rather than calling :func:`robolab.geometry.wrap_angle`, which the
    grader disables while ``wrap`` is graded (``robolab.grading.loading.delegation``).
    """
    a = np.asarray(angle, dtype=float)
    # Subtract the whole turns that take a into [-pi, pi): k = floor((a + pi) / 2 pi).
    wrapped = a - 2.0 * np.pi * np.floor((a + np.pi) / (2.0 * np.pi))
    # Rounding can land exactly on +pi (a just below -pi, or at an odd multiple of pi).
    wrapped = np.where(wrapped >= np.pi, wrapped - 2.0 * np.pi, wrapped)
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def mean_pose(poses) -> np.ndarray:
    """Mean of ``(N, 3)`` poses: the arithmetic mean of x and y, the circular mean of theta.

    Parameters
    ----------
    poses : array_like, shape (N, 3)
        Poses ``(x, y, theta)``, N >= 1.

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``(mean x, mean y, mean direction)`` with the angle wrapped to [-pi, pi).

    Raises
    ------
    ValueError
        When ``poses`` is not an ``(N, 3)`` array with N >= 1.
    """
    p = as_array("poses", poses, shape=(None, POSE_WIDTH), finite=True)
    if p.shape[0] == 0:
        raise ValueError("poses must hold at least one pose, got shape (0, 3)")
    return np.array([p[:, 0].mean(), p[:, 1].mean(), _circular_mean(p[:, 2])])
