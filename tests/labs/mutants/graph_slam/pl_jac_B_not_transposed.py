"""B = R_i instead of R_i^T.

class: formula
"""

import numpy as np

from solutions.graph_slam import _last_dim


def pose_landmark_jacobians(x, landmark, z):
    x = _last_dim("x", x, 3)
    lm = _last_dim("landmark", landmark, 2)
    z = _last_dim("z", z, 2)
    shape = np.broadcast_shapes(x.shape[:-1], lm.shape[:-1], z.shape[:-1])
    x, lm = np.broadcast_to(x, shape + (3,)), np.broadcast_to(lm, shape + (2,))
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    dx, dy = lm[..., 0] - x[..., 0], lm[..., 1] - x[..., 1]
    R = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)
    B = np.swapaxes(R, -1, -2)
    A = np.concatenate([-R, np.stack([-s * dx + c * dy, -c * dx - s * dy], -1)[..., None]], -1)
    return A, B
