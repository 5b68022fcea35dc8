"""A value exactly at the threshold is clipped to free (m > tau instead of m >= tau).

Boundary values of a validity interval.

class: boundary
"""

import numpy as np

from robolab.maps import UNKNOWN
from robolab.validation import as_array, check_positive


def clip_map(occupancy, threshold=0.5):
    r"""Clip an occupancy map to 0 / 1 at ``threshold`` (the seed's clipping); unknown stays -1.

    .. math::

        \hat m_i = \begin{cases} 1 & m_i \ge \tau \\ 0 & 0 \le m_i < \tau \\
                                  -1 & m_i = -1 \ (\text{unknown}) \end{cases}

    A value exactly at the threshold counts as occupied, as in
    :attr:`robolab.maps.OccupancyGrid.occupied`.

    Parameters
    ----------
    occupancy : array_like
        Occupancy in [0, 1], or -1 for unknown cells.
    threshold : float
        ``tau`` in [0, 1] (default 0.5).

    Returns
    -------
    numpy.ndarray of float, same shape
        Values in {-1, 0, 1}.
    """
    m = as_array("occupancy", occupancy, finite=True)
    known = m != UNKNOWN
    if np.any((m[known] < 0) | (m[known] > 1)):
        raise ValueError("occupancy values must be in [0, 1] or -1 (unknown)")
    tau = check_positive("threshold", threshold, allow_zero=True)
    if tau > 1:
        raise ValueError(f"threshold must be in [0, 1], got {threshold!r}")
    return np.where(known, (m > tau).astype(float), UNKNOWN)
