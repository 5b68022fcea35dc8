"""Skips the shape check: a pose of two numbers fails with an IndexError, not a clear ValueError.

class: refusal
"""

import numpy as np

from robolab.geometry import wrap_angle


def pose_pose_error(xi, xj, z):
    xi, xj, z = np.broadcast_arrays(
        np.asarray(xi, dtype=float), np.asarray(xj, dtype=float), np.asarray(z, dtype=float)
    )
    ci, si = np.cos(xi[..., 2]), np.sin(xi[..., 2])
    dx, dy = xj[..., 0] - xi[..., 0], xj[..., 1] - xi[..., 1]
    u0, u1 = ci * dx + si * dy - z[..., 0], -si * dx + ci * dy - z[..., 1]
    cz, sz = np.cos(z[..., 2]), np.sin(z[..., 2])
    return np.stack(
        [cz * u0 + sz * u1, -sz * u0 + cz * u1, wrap_angle(xj[..., 2] - xi[..., 2] - z[..., 2])], -1
    )
