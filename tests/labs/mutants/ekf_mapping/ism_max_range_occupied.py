"""A max-range reading marks the cells at zmax occupied.

Boundary values of a validity interval.

class: boundary
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
    _scan,
    _state,
)


def inverse_sensor_model(
    grid_shape, state, scan, max_range=MAX_RANGE, beam_angles=None, beam_width=None
):
    """Per-cell evidence of one scan: +1 hit, -0.2 passed, 0 not reached.

    The seed's provided ``inverse_sense_model``, i.e. Probabilistic Robotics'
    ``inverse_range_sensor_model`` (Table 9.2) with ``l_occ = +1``,
    ``l_free = -0.2``, ``l_0 = 0``, obstacle thickness ``alpha`` = one cell
    and opening angle ``beta`` = ``beam_width``, evaluated for every cell at
    once. For the centre of cell ``i`` at distance ``r_i`` and bearing
    ``phi_i`` from the robot, take the beam ``k`` whose direction is closest
    to ``phi_i``:

    .. math::

        \\ell_i = \\begin{cases}
          0 & r_i > \\min(z_{max},\\, z_k + \\alpha/2)
              \\ \\text{or}\\ |\\phi_i - \\theta_k| > \\beta/2
              \\quad\\text{(not reached)}\\\\
          +1 & z_k < z_{max}\\ \\text{and}\\ |r_i - z_k| < \\alpha/2
              \\quad\\text{(the beam ends here)}\\\\
          -0.2 & r_i \\le z_k \\quad\\text{(the beam passes)}
        \\end{cases}

    A reading of ``max_range`` (or more, or ``inf``: no return) hits nothing,
    so every cell it reaches is free.

    Parameters
    ----------
    grid_shape : (int, int)
        ``(H, W)`` of the map; one unit per cell, origin at the corner of cell ``(0, 0)``.
    state : array_like, shape (3,)
        Sensor pose ``(x, y, theta)``.
    scan : array_like, shape (B,)
        Measured ranges, >= 0; ``inf`` means no return. NaN is rejected.
    max_range : float
        ``zmax``, > 0.
    beam_angles : array_like, shape (B,), optional
        Beam directions relative to the heading (rad); default
        ``2 pi k / B`` (the seed's sensor).
    beam_width : float, optional
        Opening angle ``beta`` of a beam (rad); default ``2 pi / B``, the
        spacing of the seed's beams, so that every cell within range belongs
        to a beam.

    Returns
    -------
    numpy.ndarray, shape (H, W)
        Values in ``{-0.2, 0, 1}``.

    Raises
    ------
    ValueError
        A bad shape, a scan that is empty, has NaN or negative ranges, or does
        not match ``beam_angles``.
    """
    shape = _grid_shape(grid_shape)
    s = _state(state)
    zmax = check_positive("max_range", max_range)
    z = _scan(scan, zmax)
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
    occ = ~unseen & (np.abs(r - zk) < alpha / 2)
    free = ~unseen & ~occ & (r <= zk)
    return np.where(occ, L_OCC, np.where(free, L_FREE, L_UNSEEN))
