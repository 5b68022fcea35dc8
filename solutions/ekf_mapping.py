"""Lab 06 reference solution: EKF localization with grid mapping (seed 000, section 4, appendix A).

The robot is a unicycle driven by ``(speed, rotation_speed)`` commands; it
carries a 36-beam range sensor (one beam every 10 degrees, ``zmax = 20``).
One step of the seed's ``GOMapping``:

1. **predict** the pose with the unicycle transition model and its Jacobian
   (Probabilistic Robotics, Table 3.3, lines 2-3 with Table 7.1's
   linearization);
2. **map**: add the inverse sensor model of the scan, taken at the predicted
   pose, to the map (the seed's ``mapping``; Table 9.2);
3. **correct** with the 36 ranges ray-cast in that map (Table 3.3, lines 4-6).

The map is the seed's *evidence* map: a plain ``(H, W)`` float array of
accumulated scores (``+1`` per hit, ``-0.2`` per pass-through, ``0`` never
seen), ``map[row, col]`` with row = y, one world unit per cell and the origin
at the corner of cell ``(0, 0)``: cell ``(r, c)`` covers
``[c, c + 1) x [r, r + 1)``. Scores are not probabilities, so the map is not
an :class:`~robolab.maps.OccupancyGrid`; a cell counts as an obstacle for ray
casting when its score exceeds ``0.5`` (the seed's threshold), which
:func:`measurement_function` applies when it is handed an array.
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from robolab.geometry import wrap_angle
from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays
from robolab.validation import as_array, check_covariance, check_finite, check_positive

__all__ = [
    "transition_model",
    "state_jacobian",
    "measurement_function",
    "measurement_jacobian",
    "inverse_sensor_model",
    "update_map",
    "ekf_mapping_step",
]

#: The seed's sensor: 36 beams, one every 10 degrees, range 20 units.
N_BEAMS = 36
MAX_RANGE = 20.0
#: Inverse sensor model values (the seed's provided ``inverse_sense_model``).
L_OCC = 1.0
L_FREE = -0.2
L_UNSEEN = 0.0
#: An evidence score above this is an obstacle (the seed's ``map(x, y) > 0.5``).
OCCUPIED_SCORE = 0.5
#: Central-difference steps of :func:`measurement_jacobian`: (x, y) in cells, theta in rad.
JACOBIAN_STEPS = (0.1, 0.1, 0.01)


def transition_model(state, speed, rotation_speed, dt):
    """Predict the pose with the seed's unicycle model (``transitionModel``).

    The Euler step of the velocity motion model (Probabilistic Robotics,
    section 5.3, without noise), the mean prediction ``g(u_t, mu_{t-1})`` of
    the EKF (Table 3.3, line 2):

    .. math::

        x' = x + v \\cos\\theta \\,\\Delta t, \\qquad
        y' = y + v \\sin\\theta \\,\\Delta t, \\qquad
        \\theta' = \\mathrm{wrap}(\\theta + \\omega \\,\\Delta t)

    The position moves along the *old* heading, as in the seed.

    Parameters
    ----------
    state : array_like, shape (3,) or (N, 3)
        Pose(s) ``(x, y, theta)``; units per cell and radians.
    speed : float
        Forward speed ``v`` (units/s).
    rotation_speed : float
        Turn rate ``omega`` (rad/s).
    dt : float
        Time step (s), > 0.

    Returns
    -------
    numpy.ndarray, same shape as ``state``
        The predicted pose(s), heading wrapped to ``[-pi, pi)``.

    Raises
    ------
    ValueError
        ``state`` is not ``(3,)``/``(N, 3)`` or not finite, a speed is not
        finite, ``dt`` is not > 0.
    """
    s = _state(state, allow_many=True)
    v = check_finite("speed", speed)
    w = check_finite("rotation_speed", rotation_speed)
    dt = check_positive("dt", dt)
    theta = s[..., 2]
    out = np.empty_like(s)
    out[..., 0] = s[..., 0] + v * np.cos(theta) * dt
    out[..., 1] = s[..., 1] + v * np.sin(theta) * dt
    out[..., 2] = wrap_angle(theta + w * dt)
    return out


def state_jacobian(state, speed, rotation_speed, dt):
    """Jacobian ``G_t = dg/dx`` of :func:`transition_model` (the seed's ``stateJacobian``).

    Probabilistic Robotics, Table 3.3 line 3 (``Sigma = G Sigma G^T + R``):

    .. math::

        G = \\begin{pmatrix}
            1 & 0 & -v \\sin\\theta \\,\\Delta t \\\\
            0 & 1 & \\phantom{-}v \\cos\\theta \\,\\Delta t \\\\
            0 & 0 & 1
        \\end{pmatrix}

    ``rotation_speed`` does not enter (the heading update is additive) but is
    kept so that both functions share one signature.

    Parameters
    ----------
    state : array_like, shape (3,)
        Pose ``(x, y, theta)`` at which to linearize.
    speed, rotation_speed, dt : float
        As in :func:`transition_model`.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
    """
    s = _state(state)
    v = check_finite("speed", speed)
    check_finite("rotation_speed", rotation_speed)
    dt = check_positive("dt", dt)
    g = np.eye(3)
    g[0, 2] = -v * np.sin(s[2]) * dt
    g[1, 2] = v * np.cos(s[2]) * dt
    return g


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
    g = _as_grid(grid)
    angles = _beam_angles(n_beams)
    return cast_rays(g, s, angles, check_positive("max_range", max_range))[0]


def measurement_jacobian(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE, steps=JACOBIAN_STEPS):
    """Jacobian ``H = dh/dx`` of :func:`measurement_function` by central differences.

    .. math::

        H_{kj} \\approx \\frac{h_k(x + \\delta_j e_j) - h_k(x - \\delta_j e_j)}{2 \\delta_j},
        \\qquad j \\in \\{x, y, \\theta\\}

    (Probabilistic Robotics, Table 3.3 line 4 needs ``H_t``; the seed lets
    MATLAB's ``trackingEKF`` approximate it numerically in the same way).
    All six perturbed poses are ray-cast in one :func:`cast_rays` call.

    A ray-cast range is only *piecewise* differentiable: while a beam ends on
    one straight face of an obstacle, its range is linear in ``x`` and ``y``
    and smooth in ``theta``, so any step inside that piece gives the exact
    slope (up to ``O(delta^2)`` in ``theta``). Where the beam slides off a
    corner onto another obstacle, or starts or stops reaching ``max_range``,
    the range jumps; a difference straddling the jump returns
    ``jump / (2 delta)``, not a derivative. The default steps, 0.1 cell in
    position and 0.01 rad in heading (0.2 cell across at a range of 20), keep
    most beams inside one piece while staying far above round-off; smaller
    steps make the (rare) straddling entries larger, larger steps make them
    more frequent.

    Parameters
    ----------
    state, grid, n_beams, max_range
        As in :func:`measurement_function`.
    steps : (float, float, float)
        Half-widths ``delta`` for x, y (units) and theta (rad), each > 0.

    Returns
    -------
    numpy.ndarray, shape (n_beams, 3)
    """
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
    return ((r[0::2] - r[1::2]) / (2.0 * d[:, None])).T


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
    occ = ~unseen & (zk < zmax) & (np.abs(r - zk) < alpha / 2)
    free = ~unseen & ~occ & (r <= zk)
    return np.where(occ, L_OCC, np.where(free, L_FREE, L_UNSEEN))


def update_map(grid, state, scan, max_range=MAX_RANGE):
    """Add one scan's inverse sensor model to the evidence map (the seed's ``mapping``).

    .. math:: m_i \\leftarrow m_i + \\ell_i(x_t, z_t)

    the additive update of occupancy grid mapping (Probabilistic Robotics,
    Table 9.1, line 4, with the seed's scores in place of log odds and no
    prior term). Cells no beam reaches are unchanged, so a map that starts at
    0 keeps 0 where nothing was seen.

    Parameters
    ----------
    grid : array_like, shape (H, W)
        The evidence map (not modified).
    state : array_like, shape (3,)
        Pose from which the scan was taken.
    scan : array_like, shape (B,)
        Ranges, beams evenly spread over the circle (see :func:`inverse_sensor_model`).
    max_range : float
        ``zmax``.

    Returns
    -------
    numpy.ndarray, shape (H, W)
        The new map.

    Raises
    ------
    TypeError
        ``grid`` is an OccupancyGrid: the evidence map is an array of scores.
    ValueError
        ``grid`` not a finite (H, W) array, ``state`` not (3,), or a scan that is
        empty or has NaN or negative ranges (as :func:`inverse_sensor_model`).
    """
    if isinstance(grid, OccupancyGrid):
        raise TypeError(
            "grid must be the evidence map as an (H, W) array of scores "
            "(start from np.zeros((H, W))), "
            "not an OccupancyGrid: scores are not occupancy probabilities"
        )
    m = as_array("grid", grid, ndim=2, finite=True)
    return m + inverse_sensor_model(m.shape, state, scan, max_range)


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

    Raises
    ------
    ValueError
        A ``scan`` whose length is not the size of ``R``, or with NaN or negative
        ranges; a non-finite ``speed`` or ``rotation_speed``; ``dt <= 0`` or
        ``max_range <= 0``; a ``grid`` that is not a finite (H, W) array.
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
    f.x[2] = wrap_angle(f.x[2])
    return f.x.copy(), np.array(f.P, dtype=float), new_map


# -- helpers -------------------------------------------------------------------------------


def _state(state, allow_many=False) -> np.ndarray:
    s = as_array("state", state, ndim=(1, 2) if allow_many else 1, finite=True)
    if s.shape[-1] != 3:
        raise ValueError(
            f"state must be a pose (x, y, theta){' or (N, 3) poses' if allow_many else ''}, "
            f"got shape {s.shape}"
        )
    return s.copy()


def _beam_angles(n_beams) -> np.ndarray:
    if isinstance(n_beams, bool) or not isinstance(n_beams, (int, np.integer)) or n_beams < 1:
        raise ValueError(f"n_beams must be a positive integer, got {n_beams!r}")
    return 2.0 * np.pi * np.arange(n_beams) / n_beams


def _as_grid(grid) -> OccupancyGrid:
    """An OccupancyGrid as it is; an evidence array as a unit grid, obstacles where score > 0.5."""
    if isinstance(grid, OccupancyGrid):
        return grid
    m = as_array("grid", grid, ndim=2, finite=True)
    if m.size == 0:
        raise ValueError("grid must be a non-empty (H, W) map")
    return OccupancyGrid((m > OCCUPIED_SCORE).astype(float), 1.0)


def _nearest_beam(phi, angles):
    """Index of the beam closest in direction to each bearing, and the absolute angle to it.

    The beam directions are sorted on the circle once; each bearing is placed
    between two neighbours by binary search, O(n log B) instead of comparing
    against every beam.
    """
    two_pi = 2.0 * np.pi
    a = np.mod(angles, two_pi)
    order = np.argsort(a, kind="stable")
    a_sorted = a[order]
    p = np.mod(phi, two_pi)
    hi = np.searchsorted(a_sorted, p) % a.size  # next beam counter-clockwise (wraps around)
    lo = (hi - 1) % a.size  # previous beam
    d_hi = np.abs(wrap_angle(p - a_sorted[hi]))
    d_lo = np.abs(wrap_angle(p - a_sorted[lo]))
    use_lo = d_lo <= d_hi
    return order[np.where(use_lo, lo, hi)], np.where(use_lo, d_lo, d_hi)


def _grid_shape(grid_shape) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in grid_shape)
        ok = all(float(v) == int(v) for v in grid_shape)
    except (TypeError, ValueError) as exc:
        raise TypeError(
            f"grid_shape must be a pair of integers (H, W), got {grid_shape!r}"
        ) from exc
    if not ok or h < 1 or w < 1:
        raise ValueError(f"grid_shape must be two positive integers (H, W), got {grid_shape!r}")
    return h, w


def _scan(scan, max_range) -> np.ndarray:
    """Ranges as floats; NaN and negative values raise, inf and readings past zmax become zmax."""
    z = as_array("scan", scan, ndim=1)
    if z.shape[0] == 0:
        raise ValueError("scan must hold at least one range")
    if np.any(np.isnan(z)):
        raise ValueError("scan must not contain NaN ranges")
    if np.any(z < 0):
        raise ValueError(f"scan ranges must be >= 0, got minimum {z.min()}")
    return np.minimum(z, max_range)


def _as_filter(ekf) -> ExtendedKalmanFilter:
    """The given ExtendedKalmanFilter (x flattened to (3,)), or a new one made of (x, P, Q, R)."""
    if isinstance(ekf, ExtendedKalmanFilter):
        f = ekf
        x, p, q, r = f.x, f.P, f.Q, f.R
    else:
        if isinstance(ekf, dict):
            missing = [k for k in ("x", "P", "Q", "R") if k not in ekf]
            if missing:
                raise ValueError(f"ekf dict lacks {', '.join(missing)}; expected keys x, P, Q, R")
            x, p, q, r = (ekf[k] for k in ("x", "P", "Q", "R"))
        elif isinstance(ekf, (tuple, list)) and len(ekf) == 4:
            x, p, q, r = ekf
        else:
            raise TypeError(
                f"ekf must be an ExtendedKalmanFilter or (x, P, Q, R), got {type(ekf).__name__}"
            )
        f = None
    x = as_array("ekf x", x, finite=True).reshape(-1)
    if x.shape != (3,):
        raise ValueError(f"ekf x must hold 3 numbers (x, y, theta), got shape {np.shape(x)}")
    p = check_covariance("ekf P", p, 3)
    q = check_covariance("ekf Q", q, 3)
    r = as_array("ekf R", r, ndim=2, finite=True)
    if r.shape[0] != r.shape[1] or r.shape[0] < 1:
        raise ValueError(f"ekf R must be a square (B, B) matrix, got shape {r.shape}")
    r = check_covariance("ekf R", r, r.shape[0])
    if f is None:
        f = ExtendedKalmanFilter(dim_x=3, dim_z=r.shape[0])
    f.x, f.P, f.Q, f.R = x.copy(), p.copy(), q.copy(), r.copy()
    return f
