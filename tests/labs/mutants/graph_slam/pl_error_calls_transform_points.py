"""Calls the library's transform_points with the inverse pose instead of writing the error.

class: delegation
"""

import numpy as np

from robolab.geometry import inverse, transform_points
from solutions.graph_slam import _last_dim


def pose_landmark_error(x, landmark, z):
    x, lm, z = _last_dim("x", x, 3), _last_dim("landmark", landmark, 2), _last_dim("z", z, 2)
    if x.ndim == 1:
        return transform_points(lm[None], inverse(x))[0] - z
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    dx, dy = lm[..., 0] - x[..., 0], lm[..., 1] - x[..., 1]
    return np.stack([c * dx + s * dy - z[..., 0], -s * dx + c * dy - z[..., 1]], -1)
