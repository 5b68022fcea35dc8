"""Averages the headings as plain numbers: pi - 0.1 and -pi + 0.1 average to 0.

class: angle-wrap
"""

import numpy as np


def mean_pose(poses):
    p = np.asarray(poses, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError("poses must be an (N, 3) array with N >= 1")
    return p.mean(axis=0)
