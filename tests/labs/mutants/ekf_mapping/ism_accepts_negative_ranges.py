"""Negative ranges are not refused.

Inputs the notebook says to refuse.

class: refusal
"""

import numpy as np

from robolab.maps import OccupancyGrid
from robolab.validation import as_array, check_positive
from solutions.ekf_mapping import (
    L_FREE,
    L_OCC,
    L_UNSEEN,
    MAX_RANGE,
    _beam_angles,
    _grid_shape,
    _nearest_beam,
    _state,
)


def inverse_sensor_model(
    grid_shape, state, scan, max_range=MAX_RANGE, beam_angles=None, beam_width=None
):
    shape = _grid_shape(grid_shape)
    s = _state(state)
    zmax = check_positive("max_range", max_range)
    z = as_array("scan", scan, ndim=1)
    if z.shape[0] == 0 or np.any(np.isnan(z)):
        raise ValueError("scan must hold ranges and no NaN")
    z = np.minimum(z, zmax)
    b = z.shape[0]
    if beam_angles is None:
        angles = _beam_angles(b)
    else:
        angles = as_array("beam_angles", beam_angles, ndim=1, finite=True)
        if angles.shape[0] != b:
            raise ValueError(
                f"scan must have one range per beam angle ({angles.shape[0]}), got {b}"
            )
    beta = 2.0 * np.pi / b if beam_width is None else check_positive("beam_width", beam_width)
    alpha = 1.0  # obstacle thickness: one cell

    # cell centres through the library (the one place for cell <-> world)
    cx, cy = OccupancyGrid(np.zeros(shape), 1.0).cell_centers()
    dx, dy = cx - s[0], cy - s[1]
    r = np.hypot(dx, dy)
    phi = np.arctan2(dy, dx) - s[2]  # bearing of every cell centre in the robot frame
    k, offk = _nearest_beam(phi, angles)  # (H, W) closest beam and the angle to it
    zk = z[k]

    unseen = (r > np.minimum(zmax, zk + alpha / 2)) | (offk > beta / 2)
    occ = ~unseen & (zk < zmax) & (np.abs(r - zk) < alpha / 2)
    free = ~unseen & ~occ & (r <= zk)
    return np.where(occ, L_OCC, np.where(free, L_FREE, L_UNSEEN))
