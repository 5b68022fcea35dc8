"""The expected bearing atan2(dy, dx) - theta is not wrapped to [-pi, pi).

class: angle-wrap
"""

import numpy as np

from solutions.ekf_slam import _landmark_ids, _mean


def observation(mu, j):
    m = _mean(mu)
    ids = _landmark_ids("j", j, (m.size - 3) // 2)
    flat = np.atleast_1d(ids)
    lm = m[3:].reshape(-1, 2)[flat]
    dx, dy = lm[:, 0] - m[0], lm[:, 1] - m[1]
    q = dx * dx + dy * dy
    if np.any(q == 0):
        raise ValueError("a landmark is estimated at the robot's position")
    d = np.sqrt(q)
    z = np.column_stack([d, np.arctan2(dy, dx) - m[2]])
    H = np.zeros((len(flat), 2, m.size))
    rows = np.arange(len(flat))
    H[:, 0, 0], H[:, 0, 1] = -dx / d, -dy / d
    H[:, 1, 0], H[:, 1, 1], H[:, 1, 2] = dy / q, -dx / q, -1.0
    col = 3 + 2 * flat
    H[rows, 0, col], H[rows, 0, col + 1] = dx / d, dy / d
    H[rows, 1, col], H[rows, 1, col + 1] = -dy / q, dx / q
    return (z[0], H[0]) if np.ndim(ids) == 0 else (z, H)
