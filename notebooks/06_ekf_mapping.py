# ---
# jupyter:
#   jupytext:
#     cell_metadata_filter: tags
#     notebook_metadata_filter: kernelspec,language_info,robolab
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
#   language_info:
#     name: python
#   robolab:
#     lab: ekf_mapping
# ---

# %% [markdown]
# # Lab 06 — EKF localization with grid mapping
#
# A robot drives a loop through a simulated 40 x 40 world (one unit per cell) with a 36-beam range sensor:
# one beam every 10 degrees, range $z_{max} = 20$ units. It knows its commands (speed and rotation speed)
# and its start pose, but **not the map**. Each step of
# the filter
#
# 1. **predicts** the pose with the unicycle model (EKF prediction, Probabilistic Robotics Table 3.3),
# 2. **maps**: adds the scan's inverse sensor model, taken at the predicted pose, to an evidence map
#    (Table 9.2),
# 3. **corrects** the pose with the 36 ranges ray-cast in that map (Table 3.3 again).
#
# At the end you compare the EKF with a particle filter (the core of AMCL) on the same data,
# and find a case where the EKF fails and the particle filter does not.
#
# All distances are in map *units* (one cell), angles in radians, time in seconds.

# %%
import numpy as np
import matplotlib.pyplot as plt
from robolab.progress import progress_bar
from filterpy.kalman import ExtendedKalmanFilter

from robolab import DATA_DIR
from robolab.geometry import wrap_angle
from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays
from robolab.validation import as_array, check_positive
from robolab.plotting import new_axes
from robolab.plotting.ekf_mapping import (plot_evidence_map, plot_map_growth, plot_ekf_path, plot_errors,
                                          plot_particle_cloud)
from robolab.checks import ekf_mapping as checks

# The sensor and the inverse sensor model's constants.
N_BEAMS = 36                      # one beam every 10 degrees
MAX_RANGE = 20.0                  # z_max, units
L_OCC, L_FREE, L_UNSEEN = 1.0, -0.2, 0.0
OCCUPIED_SCORE = 0.5              # an evidence score above this is an obstacle
JACOBIAN_STEPS = (0.1, 0.1, 0.01) # central-difference steps: x, y (units), theta (rad)

# %% [markdown]
# ## The bundled world
#
# `data/ekf_world.npz` (made by `robolab data`) holds the true world, the commands, the true poses and the
# scans: `world[row, col]` with row = y (MATLAB code often indexes `map(x, y)`; here it is `world[y, x]`), `speed`
# and `rotation_speed` per step of `dt = 0.1` s, `states[k]` the true pose at time `k dt`, and
# `scans[k]` the 36 ranges measured at `states[k + 1]` (ray-cast truth plus $\mathcal N(0, 0.2^2)$).

# %%
with np.load(DATA_DIR / "ekf_world.npz") as npz:
    data = {k: npz[k] for k in npz.files}
world, speed, rotation_speed = data["world"], data["speed"], data["rotation_speed"]
truth, scans, dt = data["states"], data["scans"], float(data["dt"])
ANGLES = np.deg2rad(10.0 * np.arange(N_BEAMS))
n_steps = len(speed)
t = dt * np.arange(1, n_steps + 1)
print(f"{n_steps} steps of {dt} s, world {world.shape}, scans {scans.shape}")

ax = new_axes("The true world and the true path", "x [units]", "y [units]")
ax.imshow(world, origin="lower", extent=(0, 40, 0, 40), cmap="gray_r", vmin=0, vmax=1.5)
ax.plot(truth[:, 0], truth[:, 1], "k--", label="true path")
ax.plot(*truth[0, :2], "go", label="start")
ax.legend(loc="upper right");


# %% [markdown]
# ## 1. The motion model
#
# The motion model is an Euler step of the velocity motion model (Probabilistic Robotics
# section 5.3, without noise), the EKF's mean prediction $\bar\mu_t = g(u_t, \mu_{t-1})$ (Table 3.3, line 2):
#
# $$
# x' = x + v \cos\theta\,\Delta t, \qquad y' = y + v \sin\theta\,\Delta t, \qquad
# \theta' = \mathrm{wrap}(\theta + \omega\,\Delta t).
# $$
#
# The position moves along the **old** heading. Wrap the heading with `wrap_angle`.

# %% tags=["exercise"]
def transition_model(state, speed, rotation_speed, dt):
    """Predict the pose with the unicycle model (an Euler step of the velocity model).

    The Euler step of the velocity motion model (Probabilistic Robotics,
    section 5.3, without noise), the mean prediction ``g(u_t, mu_{t-1})`` of
    the EKF (Table 3.3, line 2):

    .. math::

        x' = x + v \\cos\\theta \\,\\Delta t, \\qquad
        y' = y + v \\sin\\theta \\,\\Delta t, \\qquad
        \\theta' = \\mathrm{wrap}(\\theta + \\omega \\,\\Delta t)

    The position moves along the *old* heading.

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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_transition_model(transition_model)


# %% [markdown]
# The EKF propagates the covariance through the linearized model, $\bar\Sigma_t = G_t \Sigma_{t-1} G_t^T + Q$
# (Table 3.3, line 3), with the Jacobian of $g$ with respect to the state:
#
# $$
# G_t = \frac{\partial g}{\partial (x, y, \theta)} =
# \begin{pmatrix} 1 & 0 & -v \sin\theta\,\Delta t \\ 0 & 1 & v \cos\theta\,\Delta t \\ 0 & 0 & 1 \end{pmatrix}.
# $$
#
# (ROS's `robot_localization` EKF linearizes the *control* noise as well; here the noise enters additively
# through $Q$.)

# %% tags=["exercise"]
def state_jacobian(state, speed, rotation_speed, dt):
    """Jacobian ``G_t = dg/dx`` of :func:`transition_model` (Probabilistic Robotics, Table 3.3).

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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_state_jacobian(state_jacobian)

# %% [markdown]
# Driving the commands through `transition_model` alone is **dead reckoning**: the executed velocities
# were noisy, so the open-loop path drifts away from the truth.

# %%
dead = np.empty((n_steps + 1, 3))
dead[0] = data["initial_state"]
for k in range(n_steps):
    dead[k + 1] = transition_model(dead[k], speed[k], rotation_speed[k], dt)
err_dead = np.hypot(*(dead[1:, :2] - truth[1:, :2]).T)
ax = new_axes("Dead reckoning against ground truth", "x [units]", "y [units]")
ax.plot(truth[:, 0], truth[:, 1], "k--", label="ground truth")
ax.plot(dead[:, 0], dead[:, 1], color="tab:orange", label="dead reckoning")
ax.legend()
print(f"dead reckoning: final position error {err_dead[-1]:.2f}, mean {err_dead.mean():.2f} units")


# %% [markdown]
# ## 2. The measurement model: 36 ray-cast ranges
#
# A simple way to predict a range walks each beam from the robot in steps of 0.1 until it finds a cell
# with a value above 0.5 or leaves the map. Beam $k$ points at $\theta + 2\pi k / 36$, and its predicted range
# is the range $z^*_k$ of the beam model (Probabilistic Robotics section 6.3):
#
# $$
# h(x, m) = \bigl(z^*_0(x, m), \dots, z^*_{35}(x, m)\bigr)^T .
# $$
#
# Instead of a 0.1-step loop, use `cast_rays(grid, pose, angles, max_range)` from `robolab.raycast`:
# it traverses the grid exactly (to the boundary of the first obstacle cell) for all beams at once.
# The map is either an `OccupancyGrid` (the true world) or the filter's **evidence map**, a plain array
# of scores that the mapping step below produces: turn it into a grid with obstacles where the score is
# above `OCCUPIED_SCORE`, e.g. `OccupancyGrid((m > OCCUPIED_SCORE).astype(float), 1.0)`.

# %% tags=["exercise"]
def measurement_function(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE):
    """Predicted ranges ``h(x, m)`` of the beams, by ray casting in the map.

    Beam ``k`` points at ``theta + 2 pi k / n_beams`` (every 10 degrees for 36
    beams); its predicted range ``z*_k``
    (Probabilistic Robotics, section 6.3) is the distance from the robot's
    position to the first obstacle cell the beam enters, or ``max_range``. The
    simplest version marches each beam in 0.1 steps; :func:`robolab.raycast.cast_rays`
    traverses the grid exactly and for all beams at once.

    Parameters
    ----------
    state : array_like, shape (3,)
        Pose ``(x, y, theta)``.
    grid : OccupancyGrid or array_like, shape (H, W)
        The map. An OccupancyGrid is used as it is (obstacle where
        ``data >= occupied_threshold``). An array is the evidence map of section 3
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_measurement_function(measurement_function)

# %%
true_grid = OccupancyGrid(world, 1.0)
z_hat = measurement_function(truth[1], true_grid)
ax = new_axes("Measured and predicted ranges at t = 0.1 s (true pose, true map)", "beam angle [deg]",
              "range [units]", equal=False, figsize=(7, 3.5))
ax.plot(np.rad2deg(ANGLES), scans[0], "o", label="measured z")
ax.plot(np.rad2deg(ANGLES), z_hat, "-", label="predicted h(x, m)")
ax.legend();


# %% [markdown]
# The EKF needs $H_t = \partial h / \partial x$ (Table 3.3, line 4). A ray-cast range has no formula to
# differentiate, so take central differences, one state variable at a time:
#
# $$
# H_{kj} \approx \frac{h_k(x + \delta_j e_j) - h_k(x - \delta_j e_j)}{2\,\delta_j}.
# $$
#
# A ray-cast range is only **piecewise** differentiable: while a beam ends on one straight face of an
# obstacle its range is linear in $x, y$ and smooth in $\theta$, but where the beam slides past a corner onto
# another obstacle (or starts reaching $z_{max}$) the range jumps, and a difference across the jump is
# $\text{jump} / 2\delta$, not a slope. Use `JACOBIAN_STEPS` ($0.1$ unit, $0.01$ rad) and ray-cast all six
# perturbed poses in one `cast_rays` call.

# %% tags=["exercise"]
def measurement_jacobian(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE, steps=JACOBIAN_STEPS):
    """Jacobian ``H = dh/dx`` of :func:`measurement_function` by central differences.

    .. math::

        H_{kj} \\approx \\frac{h_k(x + \\delta_j e_j) - h_k(x - \\delta_j e_j)}{2 \\delta_j},
        \\qquad j \\in \\{x, y, \\theta\\}

    (Probabilistic Robotics, Table 3.3 line 4 needs ``H_t``; MATLAB's
    ``trackingEKF`` approximates it numerically in the same way).
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_measurement_jacobian(measurement_jacobian)


# %% [markdown]
# ## 3. Mapping with the inverse sensor model
#
# The mapping step adds a simple inverse sensor model for every cell: for each cell it
# picks the **closest beam**; if that beam ends in the cell (and is not a max-range reading) it returns
# $+1$, if the beam passes through the cell it returns $-0.2$, and if no beam reaches the cell it returns 0.
# That is Probabilistic Robotics' `inverse_range_sensor_model` (Table 9.2) with obstacle thickness
# $\alpha$ = one cell and opening angle $\beta$ = 10 degrees. For a cell centre at distance $r$ and bearing
# $\phi$, with $k$ the beam closest in direction:
#
# $$
# \ell = \begin{cases}
# 0 & r > \min(z_{max}, z_k + \alpha/2) \text{ or } |\phi - \theta_k| > \beta/2 \\
# +1 & z_k < z_{max} \text{ and } |r - z_k| < \alpha/2 \\
# -0.2 & r \le z_k
# \end{cases}
# $$
#
# Write it for **all cells at once**: the cell centres come from
# `OccupancyGrid(np.zeros(shape), 1.0).cell_centers()`, the bearing of every centre gives the closest
# beam, and three boolean masks give the three cases. No loop over cells.

# %% tags=["exercise"]
def inverse_sensor_model(
    grid_shape, state, scan, max_range=MAX_RANGE, beam_angles=None, beam_width=None
):
    """Per-cell evidence of one scan: +1 hit, -0.2 passed, 0 not reached.

    A simple version of Probabilistic Robotics'
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
        ``2 pi k / B`` (the lab's sensor).
    beam_width : float, optional
        Opening angle ``beta`` of a beam (rad); default ``2 pi / B``, the
        spacing of the beams, so that every cell within range belongs
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_inverse_sensor_model(inverse_sensor_model)

# %%
ism = inverse_sensor_model(world.shape, truth[1], scans[0])
ax = plot_evidence_map(ism, title="Inverse sensor model of the first scan", truth=world)
ax.plot(*truth[1, :2], "r^", ms=9);


# %% [markdown]
# The map accumulates the evidence of every scan (Table 9.1, line 4, with the scores +1 / -0.2 in place of
# log odds): $m \leftarrow m + \ell(x_t, z_t)$. Cells no beam has reached stay 0.

# %% tags=["exercise"]
def update_map(grid, state, scan, max_range=MAX_RANGE):
    """Add one scan's inverse sensor model to the evidence map.

    .. math:: m_i \\leftarrow m_i + \\ell_i(x_t, z_t)

    the additive update of occupancy grid mapping (Probabilistic Robotics,
    Table 9.1, line 4, with the scores +1 / -0.2 in place of log odds and no
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_update_map(update_map)


# %% [markdown]
# ## 4. One EKF step with mapping, on filterpy
#
# In MATLAB this step would use `trackingEKF`; here it is `filterpy.kalman.ExtendedKalmanFilter`.
# filterpy's `predict()` computes `x = F x` — linear — and `P = F P Fᵀ + Q`. For the nonlinear prediction,
# set `ekf.F` to $G_t$ (at the previous mean) and **override** `predict_x` so that it applies
# `transition_model`; then `ekf.update(z, HJacobian, Hx, args=..., hx_args=...)` performs
#
# $$
# K = \bar\Sigma H^T (H \bar\Sigma H^T + R)^{-1}, \quad
# \mu = \bar\mu + K\,(z - h(\bar\mu, m)), \quad
# \Sigma = (I - K H)\,\bar\Sigma\,(I - K H)^T + K R K^T .
# $$
#
# Between the two, update the map from the **predicted** pose $\bar\mu$, then correct in the updated map.
# Accept the filter either as an `ExtendedKalmanFilter` or as plain arrays `(x, P, Q, R)` and return plain
# arrays `(state, covariance, map)`. Wrap the heading after the correction.

# %% tags=["exercise"]
def ekf_mapping_step(ekf, grid, speed, rotation_speed, scan, dt, max_range=MAX_RANGE):
    """One step of EKF localization with mapping (predict, map, correct).

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
    The map is updated at the predicted pose, not the previous one (section 6
    explains why).

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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_ekf_mapping_step(ekf_mapping_step)


# %% [markdown]
# ## 5. The run
#
# Start at the known initial pose with the process noise `Q = diag(0.0001, 0.0001, 0.08)` and
# $R = I$ (a standard deviation of one unit = one cell per range: the map is only known to the
# cell, whatever the sensor's own noise).

# %%
def run_ekf(step, x0, P0, m0, n=None, R=np.eye(N_BEAMS), snapshots=(), desc="EKF"):
    n = n_steps if n is None else n  # read at call time, not at definition
    # Run `step(ekf, map, v, w, z, dt)` over the data; return states, covariances, final map and snapshots.
    x, P, m = np.array(x0, float), np.array(P0, float), np.array(m0, float)
    states, covs, snaps = np.empty((n, 3)), np.empty((n, 3, 3)), {}
    for k in progress_bar(range(n), desc=desc, leave=False):
        x, P, m = step((x, P, data["process_noise"], R), m, speed[k], rotation_speed[k], scans[k], dt)
        states[k], covs[k] = x, P
        if round((k + 1) * dt, 6) in snapshots:
            snaps[round((k + 1) * dt, 6)] = m.copy()
    return states, covs, m, snaps

def position_error(states):
    return np.hypot(*(states[:, :2] - truth[1:len(states) + 1, :2]).T)

SNAP_TIMES = (2.0, 8.0, 20.0, 50.0)
est, covs, ekf_map, snaps = run_ekf(ekf_mapping_step, data["initial_state"], data["initial_cov"],
                                    np.zeros(world.shape), snapshots=SNAP_TIMES)
err_ekf = position_error(est)
print(f"EKF with mapping: final position error {err_ekf[-1]:.2f}, mean {err_ekf.mean():.2f} units")

# %%
plot_map_growth([snaps[s] for s in SNAP_TIMES], SNAP_TIMES, truth=world,
                paths=[est[: int(round(s / dt))] for s in SNAP_TIMES],
                suptitle="The evidence map as it grows (black outlines: true obstacles, white: EKF path)");

# %%
fig, ax = plt.subplots(figsize=(7, 7))
plot_ekf_path(est, covs, truth[1:], ax, every=25, evidence=ekf_map,
              title="EKF with mapping: estimate, 2-sigma ellipses and ground truth");

# %% [markdown]
# Compare the two printed errors: on this run the EKF with mapping ends up **worse than dead reckoning**
# (its mean error is about twice dead reckoning's final error). Nothing in the code is wrong. The filter
# corrects the pose against a map drawn from its own earlier, already erroneous poses, and it treats that
# map as exact: a map error becomes a pose error, which the next scans write into the map again. Dead
# reckoning has no such feedback; on this short, well-calibrated run its drift stays small.
#
# The ellipses are tiny — far smaller than the actual error. The filter treats the map as exact, but the map
# was built from its own (erroneous) estimates and is only known to a cell: the EKF is **overconfident**.
# Keeping the map's uncertainty and its correlation with the pose in the state is what SLAM does
# (EKF-SLAM, Probabilistic Robotics chapter 10).
# To see how much of the error comes from the map, run the same step with the **true** map, given as
# evidence so strong (±100) that a scan cannot change it: EKF localization on a known map.

# %%
known = np.where(world > 0.5, 100.0, -100.0)
est_known, covs_known, _, _ = run_ekf(ekf_mapping_step, data["initial_state"], data["initial_cov"], known,
                                      desc="EKF, known map")
err_known = position_error(est_known)
plot_errors(t, {"dead reckoning": err_dead, "EKF with mapping": err_ekf, "EKF on the known map": err_known},
            title="Position error of the EKF with and without a known map");


# %% [markdown]
# ## 6. Why map after the prediction?
#
# The step maps after `predict` and before `correct`. The usual argument: the EKF only knows the estimated
# position at that point, and mapping after the correction would lead to incorrect results in the first
# iteration, as the map has not been initialized. With an empty map every predicted range is
# $z_{max}$ and every entry of $H$ is 0, so the first correction does nothing at all ($K = 0$): the filter
# silently ignores the scan. From the second step on, correct-then-map corrects against a map made from
# the **previous** pose's scan. Below is that order, written with the same functions.

# %%
def correct_then_map_step(ekf, grid, speed_k, rotation_speed_k, scan, dt):
    # The other order: predict, correct in the OLD map, then map from the corrected pose.
    x, P, Q, R = ekf
    f = ExtendedKalmanFilter(dim_x=3, dim_z=len(scan))
    G = state_jacobian(x, speed_k, rotation_speed_k, dt)
    f.x, f.P, f.Q, f.R = transition_model(x, speed_k, rotation_speed_k, dt), G @ P @ G.T + Q, Q, R
    f.update(scan, measurement_jacobian, measurement_function, args=(grid,), hx_args=(grid,))
    f.x[2] = wrap_angle(f.x[2])
    return f.x, f.P, update_map(grid, f.x, scan)

z0 = measurement_function(data["initial_state"], np.zeros(world.shape))
H0 = measurement_jacobian(data["initial_state"], np.zeros(world.shape))
print(f"empty map: predicted ranges {np.unique(z0)}, |H| max = {np.abs(H0).max()}")
est_ctm, _, _, _ = run_ekf(correct_then_map_step, data["initial_state"], data["initial_cov"],
                           np.zeros(world.shape), desc="correct, then map")
err_ctm = position_error(est_ctm)
plot_errors(t, {"map, then correct": err_ekf, "correct, then map": err_ctm},
            title="Order of mapping and correction");
print(f"mean position error: map then correct {err_ekf.mean():.2f}, correct then map {err_ctm.mean():.2f} units")


# %% [markdown]
# That argument is about the **first** iteration: correcting against a map that is not known yet
# (here: empty) gives predicted ranges of $z_{max}$ and $H = 0$, so $K = 0$ and the scan is wasted; had the
# unknown cells been taken as obstacles instead, every predicted range would be 0 and the correction would
# push the pose anywhere. After the first step, the other order corrects against the map of the previous
# scan, which lags the robot by one step (0.1 s, at most 0.2 units) — less than a cell: the map's
# resolution is too coarse for that lag to matter.
# On this run correct-then-map ends up somewhat better (compare the printed means): both wander by less
# than a cell, and which order wins changes from run to run, because neither removes the feedback between
# map errors and pose errors described in section 5. What matters is that the correction never uses a map
# that does not yet contain the obstacles the scan sees.

# %% [markdown]
# ## 7. EKF against a particle filter (AMCL)
#
# ROS's EKF and AMCL are alike in shape: both predict with a motion model and weigh
# with a measurement model, but AMCL is more flexible (configurable motion models, laser models, number of
# beams) while the EKF is tied to one linearized model. Here is the comparison on the same data. The
# particle filter below is AMCL's core written compactly (Probabilistic Robotics Table 8.2 with the
# Gaussian part of the beam model): move every particle with noisy commands, weigh it by
# $\prod_k \mathcal N(z_k;\, z^*_k(x^{[i]}, m), \sigma^2)$ with the 36 ranges ray-cast for **all particles
# in one call**, and resample systematically (Table 4.4). It uses the true map, as AMCL does. To keep the
# run short it weighs every 5th scan (2 Hz).

# %%
def particle_filter(particles, grid, rng, n=None, every=5, sigma_z=1.0, motion_std=(0.1, 0.05), desc="PF"):
    n = n_steps if n is None else n  # read at call time, not at definition
    # Returns the mean pose after every step and the particle clouds at the weighing steps.
    p = np.array(particles, float)
    N = len(p)
    means, clouds = np.empty((n, 3)), {}
    for k in progress_bar(range(n), desc=desc, leave=False):
        v = speed[k] + motion_std[0] * rng.standard_normal(N)
        w = rotation_speed[k] + motion_std[1] * rng.standard_normal(N)
        p = np.column_stack([p[:, 0] + v * np.cos(p[:, 2]) * dt, p[:, 1] + v * np.sin(p[:, 2]) * dt,
                             wrap_angle(p[:, 2] + w * dt)])
        if k % every == every - 1:
            z_hat = cast_rays(grid, p, ANGLES, MAX_RANGE)                   # (N, 36)
            log_w = -0.5 * np.sum((scans[k] - z_hat) ** 2, axis=1) / sigma_z**2
            wts = np.exp(log_w - log_w.max())
            wts /= wts.sum()
            u = (rng.random() + np.arange(N)) / N                           # systematic resampling
            p = p[np.minimum(np.searchsorted(np.cumsum(wts), u), N - 1)]
            clouds[k] = p.copy()
        means[k] = [p[:, 0].mean(), p[:, 1].mean(), np.arctan2(np.sin(p[:, 2]).mean(), np.cos(p[:, 2]).mean())]
    return means, clouds

rng = np.random.default_rng(6)
start = data["initial_state"] + rng.multivariate_normal(np.zeros(3), data["initial_cov"], 300)
pf_means, _ = particle_filter(start, true_grid, rng)
err_pf = position_error(pf_means)
plot_errors(t, {"EKF with mapping": err_ekf, "EKF on the known map": err_known, "particle filter (300, known map)": err_pf},
            title="EKF against a particle filter, known start");
print(f"mean position error: EKF+mapping {err_ekf.mean():.2f}, EKF known map {err_known.mean():.2f}, "
      f"PF {err_pf.mean():.2f} units")

# %% [markdown]
# ### A case where the EKF fails: an unknown start
#
# Now the robot does not know where it starts (global localization; the same happens after a *kidnapping*).
# The EKF is given a wrong initial guess with a large covariance; the particle filter starts with
# particles spread uniformly over the free space.

# %%
N_STEPS_GLOBAL = 250
guess = np.array([25.0, 28.0, 1.5])           # the true start is (10, 10, 0)
est_lost, covs_lost, _, _ = run_ekf(ekf_mapping_step, guess, np.diag([100.0, 100.0, 3.0]), known,
                                    n=N_STEPS_GLOBAL, desc="EKF, wrong start")
rng = np.random.default_rng(7)
free = np.argwhere(world < 0.5)
cells = free[rng.integers(0, len(free), 2000)]
uniform = np.column_stack([cells[:, 1] + rng.random(2000), cells[:, 0] + rng.random(2000),
                           rng.uniform(-np.pi, np.pi, 2000)])
pf_global, clouds = particle_filter(uniform, true_grid, rng, n=N_STEPS_GLOBAL, sigma_z=2.0, desc="PF, global")
fig, axes = plt.subplots(1, 3, figsize=(13, 4.4))
plot_particle_cloud(uniform, truth[0], world, axes[0], title="Particle filter, global start: t = 0 s")
for ax, k in zip(axes[1:], (4, N_STEPS_GLOBAL - 1)):
    plot_particle_cloud(clouds[k], truth[k + 1], world, ax, estimate=pf_global[k],
                        title=f"Particle filter, global start: t = {(k + 1) * dt:.1f} s")
fig.tight_layout()

# %%
tg = t[:N_STEPS_GLOBAL]
plot_errors(tg, {"EKF, wrong start (known map)": position_error(est_lost),
                 "particle filter, uniform start": position_error(pf_global)},
            title="Global localization: EKF against particle filter", log=True);
print(f"after {tg[-1]:.0f} s: EKF error {position_error(est_lost)[-1]:.1f}, "
      f"PF error {position_error(pf_global)[-1]:.2f} units")

# %% [markdown]
# The EKF's belief is one Gaussian. Far from the truth, its linearization $H$ describes ranges around the
# *wrong* pose, the correction pulls towards a pose whose ranges look locally similar, and nothing ever
# tells it that another place fits much better: it stays lost. The particle filter keeps many hypotheses and
# lets the scans choose among them; its price is the ray casting for every particle (2000 x 36 rays per
# update here, against 7 x 36 for the EKF).
#
# ## Discussion
#
# 1. Why is the mapping function called after the prediction step and not after the correction? What would
#    the first correction do without a map?
#
# *Your answer here.*
#
# 2. The map in section 5 is slightly offset from the true world and its obstacles are thicker than the true
#    ones. Where do the offset and the thickness come from (think of the pose the scans were mapped from, and
#    of the 10 degree cone and the half-cell band of the inverse sensor model)?
#
# *Your answer here.*
#
# 3. The EKF's 2-sigma ellipses are much smaller than its actual error. Which uncertainty does the filter
#    leave out of its state, and what would a full EKF SLAM put into the state instead?
#
# *Your answer here.*
#
# 4. AMCL is often called more flexible than the EKF. Name two things the particle filter above could change
#    without touching the rest of the algorithm (motion model, sensor, number of beams, ...) and what the EKF
#    would need for the same change.
#
# *Your answer here.*
#
# 5. If the sensor data were noisier, how would the evidence map react (do multiple readings help to
#    provide a more accurate result?) Which of the scores +1 and -0.2 would you change, and why?
#
# *Your answer here.*
