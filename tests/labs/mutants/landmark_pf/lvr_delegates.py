"""Calls filterpy's systematic_resample (which uses numpy's global random state).

class: delegation
"""

import numpy as np
from filterpy.monte_carlo import systematic_resample


def low_variance_resample(particles, weights, rng):
    w = np.asarray(weights, dtype=float)
    if not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
        raise ValueError("weights must be finite, non-negative and not all zero")
    return np.asarray(particles)[systematic_resample(w / w.sum())]
