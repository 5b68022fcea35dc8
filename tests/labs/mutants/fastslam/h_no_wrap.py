"""The bearing atan2(dy, dx) - theta is not wrapped.

Angle wrapping far from 0 and near +-pi.

class: angle-wrap
"""

import numpy as np

from solutions.fastslam import _last_dim


def h(landmark, pose):
    lm, p = _last_dim("landmark", landmark, 2), _last_dim("pose", pose, 3)
    dx = lm[..., 0] - p[..., 0]
    dy = lm[..., 1] - p[..., 1]
    return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx) - p[..., 2]], -1)
