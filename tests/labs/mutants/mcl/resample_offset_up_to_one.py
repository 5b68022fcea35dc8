"""The single offset r is drawn from U(0, 1) instead of U(0, 1/N): pointers run past 1.

Table 4.4 with r ~ U(0, M^-1) misread as a uniform number in [0, 1).

class: formula
"""

import numpy as np

from robolab.validation import as_array, check_rng


def low_variance_resample(particles, weights, rng):
    p = as_array("particles", particles, ndim=2)
    n = p.shape[0]
    if n == 0:
        raise ValueError("particles must contain at least one particle")
    w = as_array("weights", weights, shape=(n,))
    if not np.all(np.isfinite(w)):
        raise ValueError("weights must be finite (no NaN or inf)")
    if np.any(w < 0):
        raise ValueError(f"weights must be non-negative, got minimum {w.min()}")
    total = w.sum()
    if not total > 0:
        raise ValueError(
            "weights are all zero: cannot resample (every particle has zero likelihood)"
        )
    check_rng(rng)
    r = rng.uniform(0.0, 1.0)
    c = np.cumsum(w / total)
    pointers = r + np.arange(n) / n
    idx = np.searchsorted(c, pointers, side="right")
    idx = np.minimum(idx, np.flatnonzero(w)[-1])
    return p[idx]
