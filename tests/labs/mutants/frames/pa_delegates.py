"""Lets the library's PoseTrack.at interpolate.

class: delegation
"""

import numpy as np

from robolab.bag import PoseTrack


def pose_at(stamps, poses, t):
    stamps = np.asarray(stamps, dtype=float)
    if stamps.ndim != 1 or np.any(np.diff(stamps) <= 0):
        raise ValueError("stamps must be strictly increasing")
    if np.any((np.asarray(t) < stamps[0]) | (np.asarray(t) > stamps[-1])):
        raise ValueError("t must lie within the recorded time span")
    return PoseTrack(stamps, poses).at(t)
