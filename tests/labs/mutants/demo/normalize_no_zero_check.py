"""Divides by the sum without checking it: all-zero weights give NaN instead of an error.

class: degenerate-weights
"""

import numpy as np


def normalize(weights):
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or np.any(w < 0) or not np.all(np.isfinite(w)):
        raise ValueError("weights must be 1-D, finite and non-negative")
    return w / w.sum()
