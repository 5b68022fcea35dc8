"""Returns z - R^T (l - t), the measurement minus the prediction.

class: formula
"""

import numpy as np

from solutions.graph_slam import _last_dim


def pose_landmark_error(x, landmark, z):
    x, lm, z = _last_dim("x", x, 3), _last_dim("landmark", landmark, 2), _last_dim("z", z, 2)
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    dx, dy = lm[..., 0] - x[..., 0], lm[..., 1] - x[..., 1]
    return np.stack([z[..., 0] - (c * dx + s * dy), z[..., 1] - (-s * dx + c * dy)], -1)
