"""Pairs the last pose with the one after it: a track of one recorded pose gives NaN.

With T = 1 there is no interval: clipping the index into [0, T - 2] wraps to the
last pose, and s = 0 / 0 is NaN although the docstring allows one pose.

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
    if np.any(np.diff(stamps) <= 0):
        raise ValueError("stamps must be strictly increasing (sorted by time, no duplicates)")
    tt = as_array("t", t, ndim=(0, 1), finite=True)
    scalar = tt.ndim == 0
    tt = np.atleast_1d(tt)
    if np.any((tt < stamps[0]) | (tt > stamps[-1])):
        raise ValueError("t must lie within the recorded time span (no extrapolation)")
    k = np.clip(np.searchsorted(stamps, tt, side="right") - 1, 0, max(stamps.size - 2, 0))
    following = np.minimum(k + 1, stamps.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = (tt - stamps[k]) / (stamps[following] - stamps[k])
    xy = poses[k, :2] + s[:, None] * (poses[following, :2] - poses[k, :2])
    theta = wrap_angle(poses[k, 2] + s * angle_diff(poses[following, 2], poses[k, 2]))
    out = np.column_stack([xy, theta])
    return out[0] if scalar else out
