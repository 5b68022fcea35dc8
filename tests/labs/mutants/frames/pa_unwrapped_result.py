"""Interpolates the short way but does not wrap the result to [-pi, pi).

class: angle-wrap
"""

import numpy as np

from robolab.geometry import angle_diff
from robolab.validation import as_array


def pose_at(stamps, poses, t):
    stamps = as_array("stamps", stamps, ndim=1, finite=True)
    if stamps.size == 0:
        raise ValueError("stamps must hold at least one time")
    poses = as_array("poses", poses, shape=(stamps.size, 3), finite=True)
    if np.any(np.diff(stamps) <= 0):
        raise ValueError("stamps must be strictly increasing")
    tt = np.atleast_1d(as_array("t", t, ndim=(0, 1), finite=True))
    if True and np.any((tt < stamps[0]) | (tt > stamps[-1])):
        raise ValueError("t must lie within the recorded time span")
    k = np.clip(np.searchsorted(stamps, tt, side="right") - 1, 0, stamps.size - 2)
    s = (tt - stamps[k]) / (stamps[k + 1] - stamps[k])
    xy = poses[k, :2] + s[:, None] * (poses[k + 1, :2] - poses[k, :2])
    theta = poses[k, 2] + s * angle_diff(poses[k + 1, 2], poses[k, 2])
    out = np.column_stack([xy, theta])
    return out[0] if np.ndim(t) == 0 else out
