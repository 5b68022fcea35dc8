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
