r"""Lab 00, bags and frames: laser scans, rigid transforms and odometry between stamps.

Reference solutions for ``notebooks/00_frames.ipynb`` (seed 000, task 1: the
AMCL project's ``processBag`` replays a bag's ``/tf`` and ``base_scan``).

Frames follow ROS REP-103 (x forward, y left, angles counter-clockwise, metres
and radians) and REP-105 (``map``, ``odom``, ``base_link``; here also the
laser's ``base_laser_link``). A pose ``(x, y, theta)`` places a *child* frame in
its *parent*: a point :math:`p` given in the child frame is, in the parent,

.. math::

    p^{parent} = R(\theta)\, p^{child} + t, \qquad
    R(\theta) = \begin{pmatrix} \cos\theta & -\sin\theta \\ \sin\theta & \cos\theta \end{pmatrix},
    \quad t = (x, y)^T

(Probabilistic Robotics, section 5.2, and the sensor-to-world transform of
Table 6.3, line 5).
"""

from __future__ import annotations

import numpy as np

from robolab.geometry import angle_diff, wrap_angle
from robolab.validation import as_array, check_positive

__all__ = ["scan_to_cartesian", "transform_points", "pose_at"]


def scan_to_cartesian(ranges, angles, range_min, range_max):
    r"""Endpoints of a laser scan's valid beams, in the laser's own frame.

    Beam :math:`i` with range :math:`r_i` at angle :math:`\alpha_i` ends at

    .. math::

        p_i = (r_i \cos\alpha_i,\; r_i \sin\alpha_i)

    (Probabilistic Robotics, Table 6.3, line 5, with the sensor at the origin).
    As ``sensor_msgs/LaserScan`` specifies, a reading is a real return only if
    it is finite, positive and within ``[range_min, range_max)``; everything
    else (0, ``inf``, NaN, too short, too long) means "no return" and is dropped,
    never turned into a hit. A reading of exactly ``range_max`` is a max-range
    reading (a failed return), not a wall at ``range_max``.

    Parameters
    ----------
    ranges : array_like, shape (B,)
        Measured ranges in metres, raw (may hold 0, ``inf`` and NaN).
    angles : array_like, shape (B,)
        Beam angles in radians, counter-clockwise from the laser's x axis.
    range_min, range_max : float
        The scanner's valid range interval in metres, ``0 <= range_min < range_max``.

    Returns
    -------
    numpy.ndarray, shape (P, 2)
        ``(x, y)`` in metres of the ``P <= B`` valid beams, in beam order;
        shape ``(0, 2)`` when no beam is valid.

    Raises
    ------
    ValueError
        If ``ranges`` is not 1-D, ``angles`` does not have one finite angle per
        range, or the range limits are not finite with ``0 <= range_min < range_max``.
    TypeError
        If an argument is not numeric.
    """
    ranges = as_array("ranges", ranges, ndim=1)
    angles = as_array("angles", angles, ndim=1, finite=True)
    if angles.shape != ranges.shape:
        raise ValueError(
            f"angles must hold one angle per range: ranges has shape {ranges.shape}, "
            f"angles has shape {angles.shape}"
        )
    rmin = check_positive("range_min", range_min, allow_zero=True)
    rmax = check_positive("range_max", range_max)
    if not rmin < rmax:
        raise ValueError(f"range_min must be < range_max, got {range_min!r} and {range_max!r}")
    with np.errstate(invalid="ignore"):  # NaN compares False: dropped, no warning
        valid = np.isfinite(ranges) & (ranges > 0) & (ranges >= rmin) & (ranges < rmax)
    r, a = ranges[valid], angles[valid]
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def transform_points(points, pose):
    r"""Express points given in a child frame in its parent frame.

    .. math::

        \begin{pmatrix} x' \\ y' \end{pmatrix} =
        \begin{pmatrix} \cos\theta & -\sin\theta \\ \sin\theta & \cos\theta \end{pmatrix}
        \begin{pmatrix} x \\ y \end{pmatrix} +
        \begin{pmatrix} x_c \\ y_c \end{pmatrix}

    where ``pose = (x_c, y_c, theta)`` is the child frame's pose in the parent
    (e.g. the laser in ``base_link``, or ``base_link`` in ``odom``). Rotate
    first, then translate.

    Parameters
    ----------
    points : array_like, shape (P, 2)
        Points in the child frame, metres.
    pose : array_like, shape (3,) or (N, 3)
        The child frame's pose ``(x, y, theta)`` in the parent frame (metres,
        radians); ``N`` poses transform the same points ``N`` times.

    Returns
    -------
    numpy.ndarray, shape (P, 2) for one pose, (N, P, 2) for ``N`` poses
        The points in the parent frame.

    Raises
    ------
    ValueError
        If ``points`` is not ``(P, 2)`` or ``pose`` is not ``(3,)`` or
        ``(N, 3)``, or either holds NaN or infinity.
    TypeError
        If an argument is not numeric.
    """
    pts = as_array("points", points, ndim=2, finite=True)
    if pts.shape[1] != 2:
        raise ValueError(f"points must have shape (P, 2), got {pts.shape}")
    pose = as_array("pose", pose, ndim=(1, 2), finite=True)
    if pose.shape[-1] != 3:
        raise ValueError(
            f"pose must be (x, y, theta) of shape (3,) or an (N, 3) array of poses, "
            f"got shape {pose.shape}"
        )
    # (..., 1) columns broadcast against the (P,) coordinates: (P,) or (N, P).
    c = np.cos(pose[..., 2])[..., None]
    s = np.sin(pose[..., 2])[..., None]
    x = pose[..., 0:1] + c * pts[:, 0] - s * pts[:, 1]
    y = pose[..., 1:2] + s * pts[:, 0] + c * pts[:, 1]
    return np.stack([x, y], axis=-1)


def pose_at(stamps, poses, t):
    r"""Pose at time(s) ``t`` between recorded poses (odometry, TF): linear interpolation.

    For :math:`t_k \le t \le t_{k+1}` and :math:`s = (t - t_k) / (t_{k+1} - t_k)`,

    .. math::

        x(t) &= x_k + s\,(x_{k+1} - x_k), \qquad y(t) = y_k + s\,(y_{k+1} - y_k), \\
        \theta(t) &= \operatorname{wrap}\big(\theta_k + s\,
            \operatorname{wrap}(\theta_{k+1} - \theta_k)\big),

    so the heading turns the short way round: from 3.1 to -3.1 rad it passes
    through :math:`\pi`, not through 0. This is what tf2 does when a scan's
    stamp falls between two ``/tf`` messages. Times outside the recorded span
    raise instead of extrapolating (tf2's ``ExtrapolationException``).

    Parameters
    ----------
    stamps : array_like, shape (T,)
        Times of the recorded poses in seconds, strictly increasing.
    poses : array_like, shape (T, 3)
        Recorded poses ``(x, y, theta)`` in metres and radians.
    t : float or array_like, shape (K,)
        Query time(s) in seconds, within ``[stamps[0], stamps[-1]]``.

    Returns
    -------
    numpy.ndarray, shape (3,) for a scalar ``t``, (K, 3) otherwise
        Interpolated poses, ``theta`` wrapped to ``[-pi, pi)``. At a recorded
        stamp the recorded pose is returned; a track of one pose (``T = 1``) is
        valid, and answers that pose at its stamp.

    Raises
    ------
    ValueError
        If ``stamps`` is empty, not 1-D, not strictly increasing or not finite;
        ``poses`` is not ``(T, 3)`` and finite; ``t`` is not a finite scalar or
        1-D array; or a ``t`` lies outside ``[stamps[0], stamps[-1]]``.
    TypeError
        If an argument is not numeric.
    """
    stamps = as_array("stamps", stamps, ndim=1, finite=True)
    if stamps.size == 0:
        raise ValueError("stamps must hold at least one time, got an empty array")
    poses = as_array("poses", poses, shape=(stamps.size, 3), finite=True)
    steps = np.diff(stamps)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise ValueError(
            f"stamps must be strictly increasing (sorted by time, no duplicates), "
            f"got stamps[{k}] = {stamps[k]!r} after stamps[{k - 1}] = {stamps[k - 1]!r}"
        )
    tt = as_array("t", t, ndim=(0, 1), finite=True)
    scalar = tt.ndim == 0
    tt = np.atleast_1d(tt)
    outside = (tt < stamps[0]) | (tt > stamps[-1])
    if np.any(outside):
        raise ValueError(
            f"t must lie within the recorded time span [{stamps[0]!r}, {stamps[-1]!r}] s "
            f"(no extrapolation), got t = {tt[outside][0]!r}"
        )
    if stamps.size == 1:
        out = np.repeat(poses, tt.size, axis=0)
        out[:, 2] = wrap_angle(out[:, 2])
    else:
        k = np.clip(np.searchsorted(stamps, tt, side="right") - 1, 0, stamps.size - 2)
        s = (tt - stamps[k]) / (stamps[k + 1] - stamps[k])
        xy = poses[k, :2] + s[:, None] * (poses[k + 1, :2] - poses[k, :2])
        theta = wrap_angle(poses[k, 2] + s * angle_diff(poses[k + 1, 2], poses[k, 2]))
        out = np.column_stack([xy, theta])
    return out[0] if scalar else out
