"""Rot1 = atan2(dy, dx) - theta is not wrapped: near +-pi it is off by 2 pi and the noise it scales
explodes.

Angle wrapping far from 0 and near +-pi (odometry deltas).

class: angle-wrap
"""

import math

import numpy as np

from robolab.geometry import angle_diff, wrap_angle
from robolab.validation import as_array, as_poses
from solutions.mcl import IN_PLACE_TRANSLATION, _check_rng


def sample_motion_model_odometry(particles, odom_prev, odom_now, alphas, rng, corrected=False):
    p = as_poses("particles", particles)
    if np.ndim(particles) != 2:
        raise ValueError(f"particles must have shape (N, 3), got {np.shape(particles)}")
    a = as_array("alphas", alphas, shape=(4,), finite=True, nonnegative=True)
    _check_rng(rng)
    if not isinstance(corrected, (bool, np.bool_)):
        raise TypeError(f"corrected must be a bool, got {type(corrected).__name__}")
    prev = as_array("odom_prev", odom_prev, shape=(3,), finite=True)
    now = as_array("odom_now", odom_now, shape=(3,), finite=True)
    dx, dy = now[0] - prev[0], now[1] - prev[1]
    trans = math.hypot(dx, dy)
    rot1 = 0.0 if trans < IN_PLACE_TRANSLATION else math.atan2(dy, dx) - prev[2]
    rot2 = angle_diff(angle_diff(now[2], prev[2]), rot1)
    if corrected:
        n1 = min(abs(angle_diff(rot1, 0.0)), abs(angle_diff(rot1, np.pi)))
        n2 = min(abs(angle_diff(rot2, 0.0)), abs(angle_diff(rot2, np.pi)))
    else:
        n1, n2 = rot1, rot2
    var = np.array(
        [
            a[0] * n1**2 + a[1] * trans**2,
            a[2] * trans**2 + a[3] * (n1**2 + n2**2),
            a[0] * n2**2 + a[1] * trans**2,
        ]
    )
    noise = rng.standard_normal((p.shape[0], 3)) * np.sqrt(var)
    r1 = rot1 - noise[:, 0]
    tr = trans - noise[:, 1]
    r2 = rot2 - noise[:, 2]
    heading = p[:, 2] + r1
    return np.column_stack(
        [p[:, 0] + tr * np.cos(heading), p[:, 1] + tr * np.sin(heading), wrap_angle(heading + r2)]
    )
