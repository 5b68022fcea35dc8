"""Exp of the raw log-weights: every weight underflows to 0 and 0 / 0 = NaN.

Numerics of the log form.

class: underflow
"""

import numpy as np

from robolab.validation import as_array


def normalize_log_weights(logw):
    r"""Normalized weights from log-weights, without underflow.

    .. math::

        w_i = \frac{e^{\ell_i - \max_j \ell_j}}{\sum_k e^{\ell_k - \max_j \ell_j}}

    Subtracting the maximum changes nothing mathematically but keeps the
    largest term at :math:`e^0 = 1`, so a scan of 60 beams whose
    log-likelihoods are around -300 does not become 0 / 0.

    Parameters
    ----------
    logw : array_like, shape (N,)
        Log-weights; ``-inf`` (weight 0) allowed, NaN and ``+inf`` not.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Non-negative, sums to 1.

    Raises
    ------
    ValueError
        NaN or ``+inf`` entries, an empty array, or every entry ``-inf``.
    """
    lw = as_array("logw", logw, ndim=1)
    if lw.size == 0:
        raise ValueError("logw must hold at least one log-weight")
    if np.isnan(lw).any() or np.isposinf(lw).any():
        raise ValueError("logw must not contain NaN or +inf")
    top = lw.max()
    if not np.isfinite(top):
        raise ValueError("logw is -inf everywhere: every particle has zero weight")
    w = np.exp(lw)
    return w / w.sum()
