"""Particles are drawn over every cell that is not occupied, unknown cells included.

Empty or partially known maps.

class: empty-map
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.maps import OccupancyGrid
from solutions.mcl import _check_rng, _count


def init_uniform(grid, n, rng):
    r"""Particles drawn uniformly over the free space of a map (global localization).

    A cell is drawn uniformly among the map's free cells, then a position
    uniformly *inside* that cell (not at its centre), and a heading uniformly in
    :math:`[-\pi, \pi)`:

    .. math::

        (x, y) \sim \mathcal{U}(\text{free space}), \qquad
        \theta \sim \mathcal{U}[-\pi, \pi).

    This is the prior :math:`bel(x_0)` of global localization (Probabilistic
    Robotics, section 8.3; AMCL's ``pf_init_model`` with the free-space sampler).

    Parameters
    ----------
    grid : robolab.maps.OccupancyGrid
        The map; only its known free cells (``grid.free``) receive particles.
    n : int
        Number of particles, >= 1.
    rng : numpy.random.Generator
        The only source of randomness.

    Returns
    -------
    numpy.ndarray, shape (n, 3)
        Poses ``(x, y, theta)`` in the map frame, metres and radians.

    Raises
    ------
    TypeError
        If ``grid`` is not an OccupancyGrid, ``n`` not an integer or ``rng`` not a Generator.
    ValueError
        If ``n < 1`` or the map has no free cell.
    """
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
