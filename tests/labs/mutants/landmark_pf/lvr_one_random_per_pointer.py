"""Draws a new random number for every pointer (multinomial, not low-variance).

class: formula
"""

import numpy as np

from robolab.validation import as_array, check_rng


def low_variance_resample(particles, weights, rng):
    p = as_array("particles", particles, ndim=2)
    w = as_array("weights", weights, shape=(p.shape[0],))
    if not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
        raise ValueError("weights must be finite, non-negative and not all zero")
    check_rng(rng)
    c = np.cumsum(w / w.sum())
    idx = np.searchsorted(c, rng.uniform(0.0, 1.0, p.shape[0]), side="right")
    return p[np.minimum(idx, p.shape[0] - 1)]
