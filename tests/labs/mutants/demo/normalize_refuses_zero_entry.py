"""Treats a zero weight as invalid: only strictly positive weights are accepted.

class: boundary
"""

import numpy as np


def normalize(weights):
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ValueError("weights must be 1-D, finite and positive")
    return w / w.sum()
