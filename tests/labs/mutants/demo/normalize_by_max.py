"""Scales by the largest weight instead of the sum (the largest becomes 1).

class: formula
"""

import numpy as np


def normalize(weights):
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or w.size == 0 or np.any(w < 0) or not np.all(np.isfinite(w)) or w.sum() <= 0:
        raise ValueError("weights must be 1-D, finite, non-negative and not all zero")
    return w / w.max()
