"""Unknown cells count as obstacles in the distance transform.

Empty or partially known maps.

class: empty-map
"""

import numpy as np
from scipy import ndimage

from robolab.maps import OccupancyGrid
from robolab.validation import check_positive
from solutions.mcl import _gaussian


def likelihood_field(grid, sigma_hit, max_dist):
    r"""The likelihood field of a map: distance to the nearest obstacle, precomputed per cell.

    For every cell centre :math:`c`, the Euclidean distance to the nearest
    occupied cell centre, in metres (the distance transform of the occupancy
    mask times the resolution), clipped at ``max_dist`` (AMCL's
    ``laser_likelihood_max_dist``):

    .. math::

        d(c) = \min\big(\min_{o \in \text{occupied}} \lVert c - o \rVert,\ d_{max}\big),
        \qquad
        p_{hit}(c) = \mathcal N(d(c); 0, \sigma_{hit}^2)
                   = \frac{1}{\sqrt{2\pi}\sigma_{hit}} e^{-d(c)^2 / 2\sigma_{hit}^2}

    (Probabilistic Robotics, section 6.4 and Table 6.3, ``prob(dist, sigma_hit)``).
    Unknown cells are not obstacles. A map without any obstacle has
    :math:`d = d_{max}` everywhere.

    Parameters
    ----------
    grid : robolab.maps.OccupancyGrid
    sigma_hit : float
        Standard deviation of the hit noise, metres, > 0.
    max_dist : float
        Clipping distance, metres, > 0.

    Returns
    -------
    dict
        ``"distance"``: (H, W) metres, indexed ``[row, col]`` like ``grid.data``;
        ``"likelihood"``: (H, W) :math:`p_{hit}` in 1/m;
        ``"resolution"``: float (m/cell); ``"origin"``: (3,) the grid's origin;
        ``"sigma_hit"``, ``"max_dist"``: floats. Plain data only.
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be a robolab.maps.OccupancyGrid, got {type(grid).__name__}")
    sigma = check_positive("sigma_hit", sigma_hit)
    dmax = check_positive("max_dist", max_dist)
    occupied = ~grid.free
    if occupied.any():
        dist = ndimage.distance_transform_edt(~occupied) * grid.resolution
        dist = np.minimum(dist, dmax)
    else:
        dist = np.full(grid.shape, dmax)
    return {
        "distance": dist,
        "likelihood": _gaussian(dist, sigma),
        "resolution": float(grid.resolution),
        "origin": np.array(grid.origin, dtype=float),
        "sigma_hit": sigma,
        "max_dist": dmax,
    }
