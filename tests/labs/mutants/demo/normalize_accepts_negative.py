"""Checks only the sum, so a negative weight among positive ones is accepted.

class: refusal
"""

import numpy as np


def normalize(weights):
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or w.sum() <= 0:
        raise ValueError("weights must be 1-D and sum to a positive number")
    return w / w.sum()
