"""The map is replaced by the new scan's evidence instead of accumulating it.

Empty or partially known maps.

class: empty-map
"""

from robolab.maps import OccupancyGrid
from robolab.validation import as_array
from solutions.ekf_mapping import MAX_RANGE, inverse_sensor_model


def update_map(grid, state, scan, max_range=MAX_RANGE):
    """Add one scan's inverse sensor model to the evidence map (the seed's ``mapping``).

    .. math:: m_i \\leftarrow m_i + \\ell_i(x_t, z_t)

    the additive update of occupancy grid mapping (Probabilistic Robotics,
    Table 9.1, line 4, with the seed's scores in place of log odds and no
    prior term). Cells no beam reaches are unchanged, so a map that starts at
    0 keeps 0 where nothing was seen.

    Parameters
    ----------
    grid : array_like, shape (H, W)
        The evidence map (not modified).
    state : array_like, shape (3,)
        Pose from which the scan was taken.
    scan : array_like, shape (B,)
        Ranges, beams evenly spread over the circle (see :func:`inverse_sensor_model`).
    max_range : float
        ``zmax``.

    Returns
    -------
    numpy.ndarray, shape (H, W)
        The new map.
    """
    if isinstance(grid, OccupancyGrid):
        raise TypeError(
            "grid must be the evidence map as an (H, W) array of scores "
            "(start from np.zeros((H, W))), "
            "not an OccupancyGrid: scores are not occupancy probabilities"
        )
    m = as_array("grid", grid, ndim=2, finite=True)
    return inverse_sensor_model(m.shape, state, scan, max_range)
