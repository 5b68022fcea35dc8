"""Forgets R_z^T: the position error is left in pose i's frame instead of the measured frame.

class: formula
"""

import numpy as np

from robolab.geometry import wrap_angle
from solutions.graph_slam import _pose_pose_parts


def pose_pose_error(xi, xj, z):
    xi, xj, z, local = _pose_pose_parts(xi, xj, z)
    u = local - z[..., :2]
    return np.stack(
        [
            u[..., 0],
            u[..., 1],
            wrap_angle(xj[..., 2] - xi[..., 2] - z[..., 2]),
        ],
        -1,
    )
