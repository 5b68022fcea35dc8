"""No refusal of hits > visits (occupancy above 1 is returned silently).

Inputs the notebook says to refuse.

class: refusal
"""

import numpy as np

from robolab.maps import UNKNOWN
from robolab.validation import as_array


def occupancy_from_counts(hits, visits):
    h = as_array("hits", hits, finite=True, nonnegative=True)
    v = as_array("visits", visits, shape=h.shape, finite=True, nonnegative=True)
    out = np.full(h.shape, UNKNOWN)
    seen = v > 0
    out[seen] = h[seen] / v[seen]
    return out
