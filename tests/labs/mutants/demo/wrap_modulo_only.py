"""Takes the angle modulo 2 pi, which lands in [0, 2 pi), not [-pi, pi).

class: formula
"""

import numpy as np


def wrap(angle):
    return np.asarray(angle, dtype=float) % (2 * np.pi)
