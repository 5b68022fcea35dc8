"""Any positive evidence score counts as an obstacle (> 0 instead of > 0.5).

Boundary values of a validity interval.

class: boundary
"""

from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays
from robolab.validation import as_array, check_positive
from solutions.ekf_mapping import MAX_RANGE, N_BEAMS, _beam_angles, _state


def measurement_function(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE):
    """Predicted ranges ``h(x, m)`` of the beams, by ray casting in the map.

    Beam ``k`` points at ``theta + 2 pi k / n_beams`` (every 10 degrees for 36
    beams, as the seed's ``measurementFunction``); its predicted range ``z*_k``
    (Probabilistic Robotics, section 6.3) is the distance from the robot's
    position to the first obstacle cell the beam enters, or ``max_range``. The
    seed marches each beam in 0.1 steps; :func:`robolab.raycast.cast_rays`
    traverses the grid exactly and for all beams at once.

    Parameters
    ----------
    state : array_like, shape (3,)
        Pose ``(x, y, theta)``.
    grid : OccupancyGrid or array_like, shape (H, W)
        The map. An OccupancyGrid is used as it is (obstacle where
        ``data >= occupied_threshold``). An array is the seed's evidence map
        (one unit per cell, origin 0): obstacle where the score is > 0.5.
    n_beams : int
        Number of beams, evenly spread over the full circle.
    max_range : float
        Sensor range ``zmax`` (units), > 0.

    Returns
    -------
    numpy.ndarray, shape (n_beams,)
        Predicted ranges in ``[0, max_range]``.
    """
    s = _state(state)
    g = (
        grid
        if isinstance(grid, OccupancyGrid)
        else OccupancyGrid((as_array("grid", grid, ndim=2, finite=True) > 0).astype(float), 1.0)
    )
    angles = _beam_angles(n_beams)
    return cast_rays(g, s, angles, check_positive("max_range", max_range))[0]
