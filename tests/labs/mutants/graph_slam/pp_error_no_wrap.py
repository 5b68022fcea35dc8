"""The heading error theta_j - theta_i - theta_z is not wrapped.

class: angle-wrap
"""

import numpy as np

from solutions.graph_slam import _pose_pose_parts


def pose_pose_error(xi, xj, z):
    xi, xj, z, local = _pose_pose_parts(xi, xj, z)
    u = local - z[..., :2]
    cz, sz = np.cos(z[..., 2]), np.sin(z[..., 2])
    return np.stack(
        [
            cz * u[..., 0] + sz * u[..., 1],
            -sz * u[..., 0] + cz * u[..., 1],
            xj[..., 2] - xi[..., 2] - z[..., 2],
        ],
        -1,
    )
