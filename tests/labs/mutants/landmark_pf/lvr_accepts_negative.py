"""Checks only that the weights are not all zero: NaN, infinite or negative weights pass.

class: refusal
"""

import numpy as np

from robolab.validation import as_array, check_rng


def low_variance_resample(particles, weights, rng):
    p = as_array("particles", particles, ndim=2)
    n = p.shape[0]
    w = as_array("weights", weights, shape=(n,))
    if not np.any(w != 0):
        raise ValueError("weights are all zero")
    check_rng(rng)
    r = rng.uniform(0.0, 1.0 / n)
    c = np.cumsum(w / w.sum())
    idx = np.searchsorted(c, r + np.arange(n) / n, side="right")
    idx = np.minimum(idx, np.flatnonzero(w)[-1])
    return p[idx]
