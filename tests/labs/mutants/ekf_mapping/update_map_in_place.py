"""The evidence is added into the caller's map (m += ...) and that array is returned.

In-place modification and aliasing.

class: aliasing
"""

from robolab.maps import OccupancyGrid
from robolab.validation import as_array
from solutions.ekf_mapping import MAX_RANGE, inverse_sensor_model


def update_map(grid, state, scan, max_range=MAX_RANGE):
    if isinstance(grid, OccupancyGrid):
        raise TypeError(
            "grid must be the evidence map as an (H, W) array of scores "
            "(start from np.zeros((H, W))), "
            "not an OccupancyGrid: scores are not occupancy probabilities"
        )
    m = as_array("grid", grid, ndim=2, finite=True)
    m += inverse_sensor_model(m.shape, state, scan, max_range)
    return m
