"""Does not check the shape: poses without a heading column fail with an IndexError.

class: refusal
"""

import numpy as np

from solutions.demo import _circular_mean


def mean_pose(poses):
    p = np.asarray(poses, dtype=float)
    return np.array([p[:, 0].mean(), p[:, 1].mean(), _circular_mean(p[:, 2])])
