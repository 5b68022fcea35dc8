"""Leaves the heading column of A at zero, as if the error did not depend on theta_i.

class: jacobian-point
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
    B = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)
    A = np.concatenate([-B, np.zeros(shape + (2, 1))], -1)
    return A, B
