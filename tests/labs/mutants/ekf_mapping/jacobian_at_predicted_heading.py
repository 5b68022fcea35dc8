"""G is evaluated at the predicted heading theta + omega dt instead of the previous mean.

Where a Jacobian is evaluated.

class: jacobian-point
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
    g[0, 2] = -v * np.sin(s[2] + rotation_speed * dt) * dt
    g[1, 2] = v * np.cos(s[2] + rotation_speed * dt) * dt
    return g
