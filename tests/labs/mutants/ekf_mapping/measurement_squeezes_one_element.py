"""Squeezes its result: a sensor of one beam gives a number instead of a (1,) array.

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.raycast import cast_rays
from robolab.validation import check_positive
from solutions.ekf_mapping import MAX_RANGE, N_BEAMS, _as_grid, _beam_angles, _state


def measurement_function(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE):
    s = _state(state)
    g = _as_grid(grid)
    angles = _beam_angles(n_beams)
    return np.squeeze(cast_rays(g, s, angles, check_positive("max_range", max_range))[0])
