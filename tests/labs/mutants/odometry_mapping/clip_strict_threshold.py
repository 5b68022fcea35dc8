"""A value exactly at the threshold is clipped to free (m > tau instead of m >= tau).

Boundary values of a validity interval.

class: boundary
"""

import numpy as np

from robolab.maps import UNKNOWN
from robolab.validation import as_array, check_positive


def clip_map(occupancy, threshold=0.5):
    m = as_array("occupancy", occupancy, finite=True)
    known = m != UNKNOWN
    if np.any((m[known] < 0) | (m[known] > 1)):
        raise ValueError("occupancy values must be in [0, 1] or -1 (unknown)")
    tau = check_positive("threshold", threshold, allow_zero=True)
    if tau > 1:
        raise ValueError(f"threshold must be in [0, 1], got {threshold!r}")
    return np.where(known, (m > tau).astype(float), UNKNOWN)
