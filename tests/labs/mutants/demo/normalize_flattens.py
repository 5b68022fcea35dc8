"""Flattens its input, so a 2-D array is normalized instead of refused.

class: refusal
"""

import numpy as np


def normalize(weights):
    w = np.asarray(weights, dtype=float).ravel()
    if w.size == 0 or np.any(w < 0) or not np.all(np.isfinite(w)) or w.sum() <= 0:
        raise ValueError("weights must be finite, non-negative and not all zero")
    return w / w.sum()
