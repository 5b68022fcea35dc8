"""Squeezes its result: a single weight comes back as a number instead of a (1,) array.

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.validation import as_array


def normalize(weights) -> np.ndarray:
    w = as_array("weights", weights, ndim=1, finite=True, nonnegative=True)
    if w.size and w.max() > 0:
        w = w / w.max()
    total = w.sum()
    if w.size == 0 or total <= 0.0:
        raise ValueError(
            f"weights must contain a positive entry, got {w.size} weights summing to {total}"
        )
    return np.squeeze(w / total)
