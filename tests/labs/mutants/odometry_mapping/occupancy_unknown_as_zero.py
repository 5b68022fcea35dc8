"""Cells no beam visited get 0 (free) instead of -1 (unknown).

Empty or partially known maps.

class: empty-map
"""

import numpy as np

from robolab.validation import as_array


def occupancy_from_counts(hits, visits):
    h = as_array("hits", hits, finite=True, nonnegative=True)
    v = as_array("visits", visits, shape=h.shape, finite=True, nonnegative=True)
    if np.any(h > v):
        raise ValueError("hits must not exceed visits in any cell (a hit is also a visit)")
    out = np.zeros(h.shape)
    seen = v > 0
    out[seen] = h[seen] / v[seen]
    return out
