# ruff: noqa: F841, E501 -- a student mistake leaves a variable unused; lines as the student wrote them
"""The beams point at 2 pi k / n in the world, not relative to the robot's heading.

Frames.

class: formula
"""

import numpy as np

from robolab.raycast import cast_rays
from robolab.validation import check_positive
from solutions.ekf_mapping import MAX_RANGE, N_BEAMS, _as_grid, _beam_angles, _state


def measurement_function(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE):
    s = _state(state)
    g = _as_grid(grid)
    angles = _beam_angles(n_beams)
    return cast_rays(
        g, s * np.array([1.0, 1.0, 0.0]), angles, check_positive("max_range", max_range)
    )[0]
