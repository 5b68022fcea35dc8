"""Sign error in dx/dtheta (+v sin(theta) dt).

Derivative.

class: formula
"""

import numpy as np

from robolab.validation import check_finite, check_positive
from solutions.ekf_mapping import _state


def state_jacobian(state, speed, rotation_speed, dt):
    s = _state(state)
    v = check_finite("speed", speed)
    check_finite("rotation_speed", rotation_speed)
    dt = check_positive("dt", dt)
    g = np.eye(3)
    g[0, 2] = v * np.sin(s[2]) * dt
    g[1, 2] = v * np.cos(s[2]) * dt
    return g
