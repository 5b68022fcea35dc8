"""Wraps with arctan2(sin, cos), whose interval is (-pi, pi]: pi stays pi.

class: boundary
"""

import numpy as np


def wrap(angle):
    a = np.asarray(angle, dtype=float)
    return np.arctan2(np.sin(a), np.cos(a))
