"""Lets the fiducial robot's unicycle step predict the pose (the same Euler step).

class: delegation
"""

import numpy as np

from robolab.fiducials import unicycle
from robolab.validation import check_finite, check_positive


def transition_model(state, speed, rotation_speed, dt):
    v = check_finite("speed", speed)
    w = check_finite("rotation_speed", rotation_speed)
    return unicycle(np.asarray(state, dtype=float), np.array([v, w]), check_positive("dt", dt))
