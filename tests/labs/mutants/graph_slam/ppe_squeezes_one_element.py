"""Squeezes its result: one edge given as (1, 3) arrays gives a (3,) error instead of (1, 3).

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.geometry import wrap_angle
from solutions.graph_slam import _pose_pose_parts


def pose_pose_error(xi, xj, z):
    xi, xj, z, local = _pose_pose_parts(xi, xj, z)
    u = local - z[..., :2]
    cz, sz = (np.cos(z[..., 2]), np.sin(z[..., 2]))
    return np.squeeze(
        np.stack(
            [
                cz * u[..., 0] + sz * u[..., 1],
                -sz * u[..., 0] + cz * u[..., 1],
                wrap_angle(xj[..., 2] - xi[..., 2] - z[..., 2]),
            ],
            -1,
        )
    )  # noqa: E501
