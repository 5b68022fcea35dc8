"""The bound is rounded down instead of up.

Boundary values of a validity interval.

class: boundary
"""

import numpy as np

from robolab.validation import check_positive


def kld_sample_size(k, epsilon, z):
    r"""Particles needed for KLD-sampling: the Wilson-Hilferty bound of Table 8.4.

    With :math:`k` histogram bins occupied, the number of samples such that,
    with probability :math:`1 - \delta`, the Kullback-Leibler divergence between
    the sample-based and the true posterior stays below :math:`\varepsilon` is

    .. math::

        n = \left\lceil \frac{k - 1}{2 \varepsilon}
            \left(1 - \frac{2}{9(k - 1)} + \sqrt{\frac{2}{9(k - 1)}}\, z_{1-\delta}\right)^3
            \right\rceil

    (Probabilistic Robotics, Table 8.4, line 14; Fox 2003). This is AMCL's
    ``pf_resample_limit`` with ``pop_err = epsilon`` (``kld_err``) and
    ``pop_z = z`` (``kld_z``) before its clamp to ``[min_particles,
    max_particles]``. (AMCL's default ``kld_z = 0.99`` is passed as the
    quantile itself; the 99 % quantile would be 2.326.) One bin needs one
    sample: ``kld_sample_size(1, ...) == 1``.

    Parameters
    ----------
    k : int or array_like of int
        Number of occupied bins, >= 1.
    epsilon : float
        Error bound, > 0.
    z : float
        Standard normal upper quantile :math:`z_{1-\delta}`, finite.

    Returns
    -------
    int or numpy.ndarray of int
        Same shape as ``k``.
    """
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
    n = np.floor(km1 / (2.0 * eps) * (1.0 - b + np.sqrt(b) * zq) ** 3)
    n = np.where(kk == 1, 1, np.maximum(n, 1)).astype(np.int64)
    return int(n) if n.ndim == 0 else n
