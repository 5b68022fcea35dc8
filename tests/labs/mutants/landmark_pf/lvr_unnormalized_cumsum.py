"""Walks the cumulative sum of the raw weights, assuming they already sum to 1.

class: incoming-weights
"""

import numpy as np

from robolab.validation import as_array, check_rng


def low_variance_resample(particles, weights, rng):
    p = as_array("particles", particles, ndim=2)
    n = p.shape[0]
    w = as_array("weights", weights, shape=(n,))
    if not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
        raise ValueError("weights must be finite, non-negative and not all zero")
    check_rng(rng)
    r = rng.uniform(0.0, 1.0 / n)
    c = np.cumsum(w)
    idx = np.searchsorted(c, r + np.arange(n) / n, side="right")
    idx = np.minimum(idx, np.flatnonzero(w)[-1])
    return p[idx]
