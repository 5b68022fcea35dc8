"""1 - 1 / (1 + exp(l)) written literally: loses every digit for l << 0 (cancellation).

Numerics of the log form.

class: underflow
"""

import numpy as np

from robolab.validation import as_array


def logodds_to_probability(logodds):
    l = as_array("logodds", logodds)  # noqa: E741
    if np.any(np.isnan(l)):
        raise ValueError("logodds must not contain NaN")
    return 1 - 1 / (1 + np.exp(l))
