"""No special case for k = 1: one occupied bin asks for ceil(1 / (2 eps) ...) particles, not 1.

Boundary values of a validity interval.

class: boundary
"""

import numpy as np

from robolab.validation import check_positive


def kld_sample_size(k, epsilon, z):
    kk = np.asarray(k)
    if kk.dtype == bool or not np.issubdtype(kk.dtype, np.integer):
        if not (
            np.issubdtype(kk.dtype, np.floating)
            and np.all(np.isfinite(kk))
            and np.all(kk == np.round(kk))
        ):
            raise TypeError(f"k must be an integer number of bins, got {k!r}")
    kk = kk.astype(np.int64)
    if np.any(kk < 1):
        raise ValueError(f"k must be >= 1, got minimum {kk.min()}")
    eps = check_positive("epsilon", epsilon)
    try:
        zq = float(z)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"z must be a number, got {type(z).__name__}") from exc
    if not np.isfinite(zq):
        raise ValueError(f"z must be finite, got {z!r}")
    km1 = np.maximum(kk - 1, 1).astype(float)
    b = 2.0 / (9.0 * km1)
    n = np.ceil(km1 / (2.0 * eps) * (1.0 - b + np.sqrt(b) * zq) ** 3)
    n = n.astype(np.int64)
    return int(n) if n.ndim == 0 else n
