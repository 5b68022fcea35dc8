"""1 - 1 / (1 + exp(l)) written literally: loses every digit for l << 0 (cancellation).

Numerics of the log form.

class: underflow
"""

import numpy as np

from robolab.validation import as_array


def logodds_to_probability(logodds):
    r"""Occupancy probability from log-odds (Probabilistic Robotics, Table 9.1, last line).

    .. math:: p(m_i) = 1 - \frac{1}{1 + \exp(l_i)}

    computed stably (no overflow for large ``|l|``; ``l = +-inf`` gives 1 / 0).

    Parameters
    ----------
    logodds : array_like
        Log-odds, any shape; NaN is rejected.

    Returns
    -------
    numpy.ndarray of float, same shape
        Probabilities in [0, 1]; 0.5 where the log-odds are 0.
    """
    l = as_array("logodds", logodds)  # noqa: E741
    if np.any(np.isnan(l)):
        raise ValueError("logodds must not contain NaN")
    return 1 - 1 / (1 + np.exp(l))
