"""A's theta column uses the measured translation t_z instead of the estimate's t_j - t_i (right only at zero error).

class: jacobian-point
"""

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from robolab.geometry import wrap_angle

from solutions.graph_slam import _pose_pose_parts


def pose_pose_jacobians(xi, xj, z):
    xi, xj, z, local = _pose_pose_parts(xi, xj, z)
    ang = xi[..., 2] + z[..., 2]
    c, s = np.cos(ang), np.sin(ang)  # R_z^T R_i^T = R(-(theta_i + theta_z))
    cz, sz = np.cos(z[..., 2]), np.sin(z[..., 2])
    # dR_i^T/dtheta_i (t_j - t_i) = (local_y, -local_x), rotated by R_z^T
    gx, gy = z[..., 1], -z[..., 0]
    zero, one = np.zeros_like(c), np.ones_like(c)
    B = np.stack(
        [np.stack([c, s, zero], -1), np.stack([-s, c, zero], -1), np.stack([zero, zero, one], -1)], -2
    )
    A = -B
    A[..., 0, 2] = cz * gx + sz * gy
    A[..., 1, 2] = -sz * gx + cz * gy
    return A, B
