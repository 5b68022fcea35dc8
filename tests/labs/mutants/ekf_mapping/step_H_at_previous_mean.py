"""H is evaluated at the previous mean instead of the predicted mean.

Where a Jacobian is evaluated.

class: jacobian-point
"""

import numpy as np

from robolab.geometry import wrap_angle
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
    """One step of EKF localization with mapping (the seed's ``GOMapping``).

    Probabilistic Robotics, Table 3.3, with the map update in between:

    .. math::

        \\bar\\mu &= g(u_t, \\mu_{t-1}), \\qquad
        \\bar\\Sigma = G_t \\Sigma_{t-1} G_t^T + Q \\\\
        m_t &= m_{t-1} + \\ell(\\bar\\mu, z_t) \\\\
        K_t &= \\bar\\Sigma H_t^T (H_t \\bar\\Sigma H_t^T + R)^{-1}, \\qquad
        H_t = \\partial h(\\bar\\mu, m_t) / \\partial x \\\\
        \\mu_t &= \\bar\\mu + K_t (z_t - h(\\bar\\mu, m_t)), \\qquad
        \\Sigma_t = (I - K_t H_t) \\bar\\Sigma (I - K_t H_t)^T + K_t R K_t^T

    (``Q`` is the process noise and ``R`` the measurement noise, as filterpy
    names them; the covariance update is filterpy's Joseph form.) The
    prediction runs filterpy's :meth:`ExtendedKalmanFilter.predict` with
    ``predict_x`` overridden by the nonlinear :func:`transition_model` and
    ``F`` set to :func:`state_jacobian` at the previous mean; the correction
    is :meth:`ExtendedKalmanFilter.update` with ``Hx`` =
    :func:`measurement_function` and ``HJacobian`` = :func:`measurement_jacobian`
    in the *updated* map.

    The map is updated after the prediction, from the predicted pose ``mu_bar``:
    that is the best pose the filter knows when the scan arrives, and the
    correction needs a map that already contains the obstacles (in the very
    first step the map is empty and every predicted range would be ``zmax``).
    The seed's code passes the previous pose to ``mapping``; here it is the
    predicted one, as its text explains.

    Parameters
    ----------
    ekf : ExtendedKalmanFilter or (x, P, Q, R)
        The filter (``dim_x = 3``, ``dim_z = B``); it is advanced in place
        when given as an object. Or plain arrays: mean ``x (3,)``, covariance
        ``P (3, 3)``, process noise ``Q (3, 3)``, measurement noise ``R (B, B)``
        (also accepted as a dict with those keys); these are not modified.
    grid : array_like, shape (H, W)
        Evidence map before this step.
    speed, rotation_speed, dt : float
        Command and time step, as in :func:`transition_model`.
    scan : array_like, shape (B,)
        The measured ranges (B = the size of ``R``).
    max_range : float
        ``zmax``.

    Returns
    -------
    state : numpy.ndarray, shape (3,)
    covariance : numpy.ndarray, shape (3, 3)
    map : numpy.ndarray, shape (H, W)
    """
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
    x_prev = f.x.copy()
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
        HJacobian=lambda x, *a: measurement_jacobian(x_prev, *a),
        Hx=measurement_function,
        args=(occupancy, b, zmax),
        hx_args=(occupancy, b, zmax),
    )
    f.x = np.asarray(f.x, dtype=float).reshape(3)
    f.x[2] = wrap_angle(f.x[2])
    return f.x.copy(), np.array(f.P, dtype=float), new_map
