"""The corrected heading is not wrapped.

Angle wrapping far from 0 and near +-pi (a corrected EKF heading).

class: angle-wrap
"""

import numpy as np

from robolab.validation import as_array, check_finite, check_positive
from solutions.ekf_mapping import (
    MAX_RANGE,
    _as_filter,
    _as_grid,
    _scan,
    measurement_function,
    measurement_jacobian,
    state_jacobian,
    transition_model,
    update_map,
)


def ekf_mapping_step(ekf, grid, speed, rotation_speed, scan, dt, max_range=MAX_RANGE):
    f = _as_filter(ekf)
    b = f.R.shape[0]
    z = as_array("scan", scan, ndim=1)
    if z.shape[0] != b:
        raise ValueError(f"scan must have {b} ranges (the size of R), got {z.shape[0]}")
    zmax = check_positive("max_range", max_range)
    z = _scan(z, zmax)
    v = check_finite("speed", speed)
    w = check_finite("rotation_speed", rotation_speed)
    dt = check_positive("dt", dt)
    m = as_array("grid", grid, ndim=2, finite=True)

    # predict: filterpy's predict with the nonlinear mean prediction
    f.F = state_jacobian(f.x, v, w, dt)

    def predict_x(u=0):
        f.x = transition_model(f.x, v, w, dt)

    f.predict_x = predict_x
    try:
        f.predict()
    finally:
        del f.predict_x  # back to the class's method

    # map from the predicted pose, then correct in the updated map
    new_map = update_map(m, f.x, z, zmax)
    occupancy = _as_grid(new_map)  # one grid, so both calls share the ray caster's cache
    f.update(
        z,
        HJacobian=measurement_jacobian,
        Hx=measurement_function,
        args=(occupancy, b, zmax),
        hx_args=(occupancy, b, zmax),
    )
    f.x = np.asarray(f.x, dtype=float).reshape(3)
    return f.x.copy(), np.array(f.P, dtype=float), new_map
