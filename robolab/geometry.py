"""Angles, 2D poses and rigid transforms: the one home for frame arithmetic.

Conventions (REP-103): x forward, y left, angles counter-clockwise in radians.
A pose ``(x, y, theta)`` places a child frame in a parent frame; many poses are
an ``(N, 3)`` array. Angles are wrapped to ``[-pi, pi)`` by :func:`wrap_angle`.
"""

from __future__ import annotations

import math

import numpy as np

from robolab.validation import as_array, as_poses

__all__ = [
    "wrap_angle",
    "angle_diff",
    "compose",
    "inverse",
    "relative",
    "transform_points",
    "rotation_matrix",
    "yaw_from_quaternion",
    "quaternion_from_yaw",
    "anchor_odometry",
]


#: 2 pi as numpy's ``2.0 * np.pi`` (the modulus of :func:`wrap_angle`).
_TWO_PI = 2.0 * np.pi


def wrap_angle(angle):
    """Wrap angles to ``[-pi, pi)``.

    ``wrap_angle(pi) == -pi``; works elementwise on arrays and returns a float
    for a scalar. NaN stays NaN (a missing value); an infinite angle has no
    direction and raises ValueError.
    """
    a = np.asarray(angle, dtype=float)
    if a.ndim == 0:  # Python's float % is numpy's remainder (fmod, sign fixed), and faster
        x = float(a)
        if math.isinf(x):
            raise ValueError("angle must be finite: an infinite angle has no direction")
        x = (x + math.pi) % _TWO_PI - math.pi
        return x - _TWO_PI if x >= math.pi else x
    shifted = a + np.pi
    lo, hi = (shifted.min(), shifted.max()) if shifted.size else (0.0, 0.0)
    if 0.0 <= lo and hi < _TWO_PI:
        # Angles in [-pi, pi) already (headings, mostly): the remainder below is the
        # identity and shifted - pi stays in [-pi, pi) (exact, Sterbenz, from pi / 2 up):
        # the same bits without the masked passes.
        shifted -= np.pi
        return shifted
    if shifted.size and -_TWO_PI <= lo and hi < 2.0 * _TWO_PI:
        # The common case, angles within a turn of [-pi, pi): numpy's float remainder
        # (fmod, then + 2 pi for a negative one) without fmod, bit for bit: fmod is
        # x itself on (-2 pi, 2 pi) and x - 2 pi (exact, Sterbenz) on [2 pi, 4 pi).
        # NaN and inf fail the test and take the general path below.
        wrapped = shifted  # a new array: changed in place
        np.subtract(wrapped, _TWO_PI, out=wrapped, where=wrapped >= _TWO_PI)
        np.add(wrapped, _TWO_PI, out=wrapped, where=wrapped < 0.0)
        wrapped -= np.pi
    else:
        if np.isinf(a).any():
            raise ValueError("angle must be finite: an infinite angle has no direction")
        wrapped = shifted % _TWO_PI - np.pi
    # Just below -pi, (a + pi) % 2pi rounds up to 2pi and the result would be +pi.
    np.subtract(wrapped, _TWO_PI, out=wrapped, where=wrapped >= np.pi)
    return wrapped


def angle_diff(a, b):
    """Shortest signed difference ``a - b`` wrapped to ``[-pi, pi)``."""
    return wrap_angle(np.asarray(a, dtype=float) - np.asarray(b, dtype=float))


def rotation_matrix(theta) -> np.ndarray:
    """2 x 2 rotation matrix (or ``(..., 2, 2)`` stack) for angle(s) ``theta``."""
    t = np.asarray(theta, dtype=float)
    c, s = np.cos(t), np.sin(t)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def compose(a, b) -> np.ndarray:
    """Pose composition ``a (+) b``: pose ``b`` given in frame ``a``, expressed in ``a``'s parent.

    Broadcasts over leading dimensions; the result's angle is wrapped.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + b[..., 2])], -1)


def inverse(p) -> np.ndarray:
    """Inverse pose: ``compose(p, inverse(p)) == (0, 0, 0)``."""
    p = np.asarray(p, dtype=float)
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    x = -c * p[..., 0] - s * p[..., 1]
    y = s * p[..., 0] - c * p[..., 1]
    return np.stack([x, y, wrap_angle(-p[..., 2])], -1)


def relative(a, b) -> np.ndarray:
    """Pose of ``b`` in the frame of ``a``: ``inverse(a) (+) b``."""
    return compose(inverse(a), b)


def transform_points(points, pose) -> np.ndarray:
    """Map points from a child frame into its parent, given the child's pose in the parent.

    Parameters
    ----------
    points : array_like, shape (P, 2)
        Points in the child frame.
    pose : array_like, shape (3,) or (N, 3)
        The child frame's pose ``(x, y, theta)`` in the parent frame.

    Returns
    -------
    numpy.ndarray, shape (P, 2) for one pose, (N, P, 2) for N poses
        ``R(theta) p + t`` for every point.
    """
    pts = as_array("points", points, ndim=2)
    if pts.shape[1] != 2:
        raise ValueError(f"points must have shape (P, 2), got {pts.shape}")
    single = np.ndim(pose) == 1
    poses = as_poses("pose", pose)
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    x = poses[:, 0:1] + c * pts[:, 0] - s * pts[:, 1]
    y = poses[:, 1:2] + s * pts[:, 0] + c * pts[:, 1]
    out = np.stack([x, y], -1)
    return out[0] if single else out


def yaw_from_quaternion(x, y, z, w):
    """Yaw (rotation about z) of a unit quaternion, elementwise, wrapped to ``[-pi, pi)``."""
    x, y, z, w = (np.asarray(v, dtype=float) for v in (x, y, z, w))
    return wrap_angle(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def quaternion_from_yaw(yaw) -> np.ndarray:
    """Unit quaternion ``(x, y, z, w)`` for a rotation ``yaw`` about z; shape ``(..., 4)``."""
    h = 0.5 * np.asarray(yaw, dtype=float)
    zeros = np.zeros_like(h)
    return np.stack([zeros, zeros, np.sin(h), np.cos(h)], -1)


def anchor_odometry(odom_poses, start_pose, odom_start=None) -> np.ndarray:
    """Raw odometry placed in the map frame: ``compose(start_pose, relative(odom_start, odom))``.

    Odometry ``odom -> base_link`` starts wherever the robot's odometry frame put it
    (a real bag's first odometry pose is rarely ``(0, 0, 0)``). The motion since the
    start, ``relative(odom_start, odom)``, is what odometry measures; composing it onto
    the known start pose in the map gives the raw-odometry path in the map.
    ``compose(start_pose, odom)`` is right only when ``odom_start`` is the origin.

    Parameters
    ----------
    odom_poses : array_like, shape (T, 3) or (3,)
        Odometry poses in the ``odom`` frame.
    start_pose : array_like, shape (3,)
        The true (map) pose at the time of ``odom_start``.
    odom_start : array_like, shape (3,), optional
        The odometry pose at that time; default ``odom_poses[0]``.

    Returns
    -------
    numpy.ndarray, the shape of ``odom_poses``
        The path in the map frame; its first pose is ``start_pose`` when
        ``odom_start`` is the first odometry pose.
    """
    odom = as_array("odom_poses", odom_poses, ndim=(1, 2), finite=True)
    if odom.shape[-1] != 3 or odom.size == 0:
        raise ValueError(f"odom_poses must have shape (T, 3) or (3,), got {odom.shape}")
    start = as_array("start_pose", start_pose, shape=(3,), finite=True)
    first = odom.reshape(-1, 3)[0] if odom_start is None else odom_start
    o0 = as_array("odom_start", first, shape=(3,), finite=True)
    return compose(start, relative(o0, odom))
