"""Squeezes its result: one query time t = [t0] gives a (3,) pose instead of a (1, 3) array.

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.geometry import angle_diff, wrap_angle
from robolab.validation import as_array


def pose_at(stamps, poses, t):
    stamps = as_array("stamps", stamps, ndim=1, finite=True)
    if stamps.size == 0:
        raise ValueError("stamps must hold at least one time, got an empty array")
    poses = as_array("poses", poses, shape=(stamps.size, 3), finite=True)
    steps = np.diff(stamps)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise ValueError(
            f"stamps must be strictly increasing (sorted by time, no duplicates), got stamps[{k}] = {stamps[k]!r} after stamps[{k - 1}] = {stamps[k - 1]!r}"  # noqa: E501
        )
    tt = as_array("t", t, ndim=(0, 1), finite=True)
    scalar = tt.ndim == 0
    tt = np.atleast_1d(tt)
    outside = (tt < stamps[0]) | (tt > stamps[-1])
    if np.any(outside):
        raise ValueError(
            f"t must lie within the recorded time span [{stamps[0]!r}, {stamps[-1]!r}] s (no extrapolation), got t = {tt[outside][0]!r}"  # noqa: E501
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
    return np.squeeze(out[0] if scalar else out)
