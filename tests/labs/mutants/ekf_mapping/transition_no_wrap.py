"""The heading is not wrapped.

Angle wrapping far from 0 and near +-pi.

class: angle-wrap
"""

import numpy as np

from robolab.validation import check_finite, check_positive
from solutions.ekf_mapping import _state


def transition_model(state, speed, rotation_speed, dt):
    s = _state(state, allow_many=True)
    v = check_finite("speed", speed)
    w = check_finite("rotation_speed", rotation_speed)
    dt = check_positive("dt", dt)
    theta = s[..., 2]
    out = np.empty_like(s)
    out[..., 0] = s[..., 0] + v * np.cos(theta) * dt
    out[..., 1] = s[..., 1] + v * np.sin(theta) * dt
    out[..., 2] = theta + w * dt
    return out
