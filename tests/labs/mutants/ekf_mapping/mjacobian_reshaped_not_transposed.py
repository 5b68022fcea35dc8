"""Reshapes the (3, n_beams) differences to (n_beams, 3) instead of transposing them.

The shape is right, the entries are in the wrong places.

class: formula
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.raycast import cast_rays
from robolab.validation import as_array, check_positive
from solutions.ekf_mapping import JACOBIAN_STEPS, MAX_RANGE, N_BEAMS, _as_grid, _beam_angles, _state


def measurement_jacobian(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE, steps=JACOBIAN_STEPS):
    s = _state(state)
    g = _as_grid(grid)
    d = as_array("steps", steps, shape=(3,), finite=True)
    if np.any(d <= 0):
        raise ValueError(f"steps must be three positive numbers, got {d}")
    poses = np.repeat(s[None, :], 6, axis=0)
    poses[0::2] += np.diag(d)  # +delta_j e_j for j = 0, 1, 2
    poses[1::2] -= np.diag(d)
    poses[:, 2] = wrap_angle(poses[:, 2])
    r = cast_rays(g, poses, _beam_angles(n_beams), check_positive("max_range", max_range))
    return ((r[0::2] - r[1::2]) / (2.0 * d[:, None])).reshape(n_beams, 3)
