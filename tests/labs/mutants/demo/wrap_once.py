"""Subtracts or adds 2 pi once: right near the interval, wrong for angles several turns away.

class: angle-wrap
"""

import numpy as np


def wrap(angle):
    a = np.asarray(angle, dtype=float)
    a = np.where(a >= np.pi, a - 2 * np.pi, a)
    return np.where(a < -np.pi, a + 2 * np.pi, a)
