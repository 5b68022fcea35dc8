"""An evidence score equal to 0.5 counts as an obstacle (>= 0.5 instead of > 0.5).

Boundary values of a validity interval.

class: boundary
"""

from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays
from robolab.validation import as_array, check_positive
from solutions.ekf_mapping import MAX_RANGE, N_BEAMS, OCCUPIED_SCORE, _beam_angles, _state


def measurement_function(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE):
    s = _state(state)
    g = (
        grid
        if isinstance(grid, OccupancyGrid)
        else OccupancyGrid(
            (as_array("grid", grid, ndim=2, finite=True) >= OCCUPIED_SCORE).astype(float), 1.0
        )
    )
    angles = _beam_angles(n_beams)
    return cast_rays(g, s, angles, check_positive("max_range", max_range))[0]
