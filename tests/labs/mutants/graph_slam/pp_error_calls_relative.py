"""Calls the library's relative(z, relative(x_i, x_j)) instead of writing the error.

class: delegation
"""

import numpy as np

from robolab.geometry import relative, wrap_angle
from solutions.graph_slam import _pose_pose_parts


def pose_pose_error(xi, xj, z):
    xi, xj, z, local = _pose_pose_parts(xi, xj, z)
    return relative(z, relative(xi, xj))
    u = local - z[..., :2]
    cz, sz = np.cos(z[..., 2]), np.sin(z[..., 2])
    return np.stack(
        [
            cz * u[..., 0] + sz * u[..., 1],
            -sz * u[..., 0] + cz * u[..., 1],
            wrap_angle(xj[..., 2] - xi[..., 2] - z[..., 2]),
        ],
        -1,
    )
