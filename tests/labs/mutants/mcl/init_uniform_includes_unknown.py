"""Particles are drawn over every cell that is not occupied, unknown cells included.

Empty or partially known maps.

class: empty-map
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.maps import OccupancyGrid
from solutions.mcl import _check_rng, _count


def init_uniform(grid, n, rng):
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be a robolab.maps.OccupancyGrid, got {type(grid).__name__}")
    n = _count("n", n)
    _check_rng(rng)
    rows, cols = np.nonzero(~grid.occupied)
    if rows.size == 0:
        raise ValueError("grid has no free cell to place particles in")
    pick = rng.integers(0, rows.size, n)
    # cell_to_world maps (row, col) to the centre; an offset in [-0.5, 0.5) spans the whole cell
    rc = np.stack([rows[pick], cols[pick]], -1) + rng.uniform(-0.5, 0.5, (n, 2))
    xy = grid.cell_to_world(rc)
    theta = wrap_angle(rng.uniform(-np.pi, np.pi, n))
    return np.column_stack([xy, theta])
