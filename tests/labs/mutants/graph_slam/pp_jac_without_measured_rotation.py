"""Drops R_z^T from A and B (uses R_i^T alone).

class: formula
"""

import numpy as np

from solutions.graph_slam import _pose_pose_parts


def pose_pose_jacobians(xi, xj, z):
    xi, xj, z, local = _pose_pose_parts(xi, xj, z)
    ang = xi[..., 2]
    c, s = np.cos(ang), np.sin(ang)  # R_z^T R_i^T = R(-(theta_i + theta_z))
    cz, sz = np.ones_like(z[..., 2]), np.zeros_like(z[..., 2])
    # dR_i^T/dtheta_i (t_j - t_i) = (local_y, -local_x), rotated by R_z^T
    gx, gy = local[..., 1], -local[..., 0]
    zero, one = np.zeros_like(c), np.ones_like(c)
    B = np.stack(
        [np.stack([c, s, zero], -1), np.stack([-s, c, zero], -1), np.stack([zero, zero, one], -1)],
        -2,
    )
    A = -B
    A[..., 0, 2] = cz * gx + sz * gy
    A[..., 1, 2] = -sz * gx + cz * gy
    return A, B
