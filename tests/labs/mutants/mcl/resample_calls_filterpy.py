"""Lets filterpy's systematic_resample pick the particles (seeded from rng for reproducibility).

class: delegation
"""

import numpy as np
from filterpy.monte_carlo import systematic_resample


def low_variance_resample(particles, weights, rng):
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
        raise ValueError("weights must be finite, non-negative and not all zero")
    np.random.seed(int(rng.integers(2**32)))  # noqa: NPY002 - filterpy draws from the global state
    return np.asarray(particles, dtype=float)[systematic_resample(w / w.sum())]
