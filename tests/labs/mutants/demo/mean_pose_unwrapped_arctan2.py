"""Returns arctan2's circular mean as it is, in (-pi, pi]: a mean heading of pi is not wrapped.

class: boundary
"""

import numpy as np


def mean_pose(poses):
    p = np.asarray(poses, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError("poses must be an (N, 3) array with N >= 1")
    theta = np.arctan2(np.mean(np.sin(p[:, 2])), np.mean(np.cos(p[:, 2])))
    return np.array([p[:, 0].mean(), p[:, 1].mean(), theta])
