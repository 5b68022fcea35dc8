"""Lets the simulator's clearance_field compute the distances (unknown cells made free first).

class: delegation
"""

import numpy as np

from robolab.maps import OccupancyGrid
from robolab.sim import clearance_field
from robolab.validation import check_positive
from solutions.mcl import _gaussian


def likelihood_field(grid, sigma_hit, max_dist):
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be a robolab.maps.OccupancyGrid, got {type(grid).__name__}")
    sigma = check_positive("sigma_hit", sigma_hit)
    dmax = check_positive("max_dist", max_dist)
    known = grid.with_data(np.where(grid.unknown, 0.0, grid.data))
    if known.occupied.any():
        dist = np.minimum(clearance_field(known), dmax)
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
