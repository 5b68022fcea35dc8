"""Every weight vanishing (all log-weights -inf) is not refused: NaN weights are returned.

Degenerate weight sets.

class: degenerate-weights
"""

import numpy as np

from robolab.validation import as_array


def normalize_log_weights(logw):
    lw = as_array("logw", logw, ndim=1)
    if lw.size == 0:
        raise ValueError("logw must hold at least one log-weight")
    if np.isnan(lw).any() or np.isposinf(lw).any():
        raise ValueError("logw must not contain NaN or +inf")
    top = lw.max()
    w = np.exp(lw - top)
    return w / w.sum()
