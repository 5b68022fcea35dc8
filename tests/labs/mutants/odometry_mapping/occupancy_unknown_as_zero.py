"""Cells no beam visited get 0 (free) instead of -1 (unknown).

Empty or partially known maps.

class: empty-map
"""

import numpy as np

from robolab.validation import as_array


def occupancy_from_counts(hits, visits):
    r"""The counting map: occupancy ``hits / visits``, unknown (-1) where no beam came.

    .. math::

        m_i = \begin{cases} \mathrm{hits}_i / \mathrm{visits}_i & \mathrm{visits}_i > 0 \\
                             -1 \ (\text{unknown}) & \mathrm{visits}_i = 0 \end{cases}

    Parameters
    ----------
    hits, visits : array_like, same shape
        Non-negative counts with ``hits <= visits``.

    Returns
    -------
    numpy.ndarray of float, same shape
        Values in [0, 1], or -1 (:data:`robolab.maps.UNKNOWN`) for never-visited
        cells: ready for ``grid.with_data(...)``.
    """
    h = as_array("hits", hits, finite=True, nonnegative=True)
    v = as_array("visits", visits, shape=h.shape, finite=True, nonnegative=True)
    if np.any(h > v):
        raise ValueError("hits must not exceed visits in any cell (a hit is also a visit)")
    out = np.zeros(h.shape)
    seen = v > 0
    out[seen] = h[seen] / v[seen]
    return out
