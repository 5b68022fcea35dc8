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
#     lab: ekf_slam
# ---

# %% [markdown]
# # Lab 08 — EKF-SLAM with known correspondences
#
# *Reference: Probabilistic Robotics (Thrun, Burgard, Fox), Chapter 10, **Table 10.1** (EKF SLAM with known correspondences, p. 314), and the odometry motion model of **Table 5.6**.*
#
# Lab 07 solved SLAM with particles: each particle a guess of the robot's path, each with its own small map. EKF-SLAM keeps **one Gaussian over everything**: the robot's pose and every landmark, in one mean and one covariance,
#
# $$
# y_t = \begin{pmatrix} x & y & \theta & m_{0,x} & m_{0,y} & \cdots & m_{K-1,x} & m_{K-1,y} \end{pmatrix}^T, \qquad p(y_t \mid z_{1:t}, u_{1:t}, c_{1:t}) = \mathcal N(\mu_t, \Sigma_t),
# $$
#
# with $\Sigma_t$ of size $(3 + 2K) \times (3 + 2K)$. Its off-diagonal blocks, the **correlations** between the pose and the landmarks and between landmarks, are what this lab is about.
#
# You will write, in order: `predict`, `observation`, `correct`, `add_landmark` and `ekf_slam`. After each exercise a check cell runs a quick test. The robot and its run are those of lab 07, so you can compare the two filters on the same data; the last part runs your filter on the Freiburg course's landmark data set.
#
# Units: metres, radians, seconds. Angles are wrapped to $[-\pi, \pi)$ with `robolab.geometry.wrap_angle`.

# %%
import numpy as np
import matplotlib.pyplot as plt

from robolab.fiducials import DT, FiducialRobot, as_robot, unicycle
from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_covariance, check_positive
from robolab.plotting import new_axes, plot_landmarks, plot_poses
from robolab.plotting.ekf_slam import (correlation_matrix, plot_correlation_snapshots, plot_ekf_slam_snapshots,
                                       plot_entries_changed, plot_pose_errors)
from robolab.checks import ekf_slam as checks

# %% [markdown]
# ## 1. The fiducial robot, again
#
# The same robot and run as lab 07: a unicycle driven three times around a rounded triangle (60 s, 600 steps of $\Delta t = 0.1$ s) among five fiducials, with additive Gaussian motion noise $\mathcal N(0, Q)$ on the pose every step and range-bearing measurements with noise $\mathcal N(0, Q_t)$ (range 0.5–5 m, field of view $180^\circ$). The book calls the motion noise $R_t$; here it is the robot's `Q`, so the filter's $R$ is `run.Q`.

# %%
run = FiducialRobot(seed=0).to_run()
print(f"{run.n_steps} steps of {run.dt} s, {run.n_fiducials} fiducials, {len(run.measurements)} measurements")
print("R = run.Q: standard deviations per step", np.round(np.sqrt(np.diag(run.Q)), 4), "(m, m, rad)")
print("Qt: standard deviations", np.round(np.sqrt(np.diag(run.Qt)), 4), "(m, rad)")

dead_reckoning = [run.x0]
for u in run.commands:
    dead_reckoning.append(unicycle(dead_reckoning[-1], u, run.dt))
dead_reckoning = np.array(dead_reckoning)
dr_error = np.hypot(*(dead_reckoning[-1, :2] - run.true_poses[-1, :2]))
print(f"dead reckoning ends {dr_error:.2f} m from the true final position")

# %% [markdown]
# ## 2. The belief as two arrays
#
# | name | shape | meaning |
# |---|---|---|
# | `mu` | $(3 + 2K,)$ | $(x, y, \theta, m_{0,x}, m_{0,y}, \dots)$: landmark $j$ is at entries `3 + 2*j` and `4 + 2*j` |
# | `sigma` | $(3 + 2K, 3 + 2K)$ | its covariance: the pose block `sigma[:3, :3]`, the landmark blocks, and the cross blocks between them |
#
# The start pose defines the map's frame, so it is known exactly: $\mu_0 = (x_0, 0, \dots, 0)$ and $\Sigma_0 = 0$. A landmark not seen yet has no belief: its entries are placeholders that no step reads, and its rows and columns of $\Sigma$ stay zero until `add_landmark` writes them (section 6). The book initializes such a landmark with an *infinite* variance instead (eq. 10.10); section 6 computes the limit of that without the infinity.

# %% [markdown]
# ## 3. Prediction (Table 10.1, lines 2–5)
#
# The robot moves, the landmarks do not. With $F_x = (I_3 \;\; 0)$, the $3 \times (3 + 2K)$ matrix that picks the pose out of the state,
#
# $$
# \bar\mu = \mu + F_x^T \Delta(\mu, u), \qquad G = I + F_x^T\, \frac{\partial \Delta}{\partial x}\, F_x, \qquad \bar\Sigma = G\,\Sigma\,G^T + F_x^T R\, F_x .
# $$
#
# Two motion models:
#
# * `motion="unicycle"` (the fiducial robot), $u = (v, \omega)$: $\Delta = (v\,\Delta t \cos\theta,\; v\,\Delta t \sin\theta,\; \omega\,\Delta t)$;
# * `motion="odometry"` (the Freiburg data, Table 5.6's parameters), $u = (r_1, t, r_2)$: $\Delta = (t \cos(\theta + r_1),\; t \sin(\theta + r_1),\; r_1 + r_2)$.
#
# In both, the pose Jacobian $G_x = \partial g / \partial x$ is the identity except for its third column. **Do not build the $(3+2K) \times (3+2K)$ matrix $G$**: it differs from the identity only in the pose block, so
#
# $$
# \bar\Sigma_{xx} = G_x \Sigma_{xx} G_x^T + R, \qquad \bar\Sigma_{xm} = G_x \Sigma_{xm}, \qquad \bar\Sigma_{mx} = \bar\Sigma_{xm}^T, \qquad \bar\Sigma_{mm} = \Sigma_{mm},
# $$
#
# which costs $O(K)$ instead of $O(K^3)$. Return new arrays: leave `mu` and `sigma` as they were passed in.

# %% tags=["exercise"]
def predict(mu, sigma, command, R, dt=DT, motion="unicycle"):
    r"""EKF-SLAM prediction: move the pose, leave the landmarks (Table 10.1, lines 2-5).

    With :math:`F_x` the :math:`3 \times (3 + 2K)` matrix that selects the pose,

    .. math::

        \bar\mu = \mu + F_x^T\,\Delta(\mu, u), \qquad
        \bar\Sigma = G\,\Sigma\,G^T + F_x^T R\,F_x, \qquad
        G = I + F_x^T\,\frac{\partial \Delta}{\partial x}\,F_x .

    ``motion="unicycle"`` (the fiducial robot, ``command = (v, omega)``):
    :math:`\Delta = (v\,\Delta t\cos\theta,\ v\,\Delta t\sin\theta,\ \omega\,\Delta t)`.
    ``motion="odometry"`` (Table 5.6's parameters, ``command = (r1, t, r2)``,
    ``dt`` unused): :math:`\Delta = (t\cos(\theta + r_1),\ t\sin(\theta + r_1),\
    r_1 + r_2)`. In both, the pose Jacobian :math:`G_x = \partial g / \partial x`
    differs from the identity only in its third column.

    Only the pose block and the pose-landmark cross blocks change:
    :math:`\bar\Sigma_{xx} = G_x \Sigma_{xx} G_x^T + R`,
    :math:`\bar\Sigma_{xm} = G_x \Sigma_{xm}`, :math:`\bar\Sigma_{mm} = \Sigma_{mm}`,
    which costs O(K), not the O(K^3) of multiplying by the full :math:`G`.

    Parameters
    ----------
    mu : array_like, shape (3 + 2K,)
        State mean, K >= 1; not modified.
    sigma : array_like, shape (3 + 2K, 3 + 2K)
        State covariance (symmetric); not modified.
    command : array_like, shape (2,) or (3,)
        ``(v, omega)`` in m/s and rad/s, or ``(r1, t, r2)`` in rad, m, rad.
    R : array_like, shape (3, 3)
        Motion noise covariance in the pose's coordinates (symmetric PSD).
    dt : float
        Time step in seconds (unicycle only).
    motion : {"unicycle", "odometry"}

    Returns
    -------
    mu : numpy.ndarray, shape (3 + 2K,)
        New array; heading wrapped to ``[-pi, pi)``.
    sigma : numpy.ndarray, shape (3 + 2K, 3 + 2K)
        New array, symmetric.

    Raises
    ------
    ValueError
        ``mu`` not of length 3 + 2K (K >= 1), ``sigma`` not of shape (3 + 2K, 3 + 2K),
        a ``command`` not of the motion's length (2 for the unicycle, 3 for odometry),
        an unknown ``motion``, or a non-finite value.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_predict(predict)

# %% [markdown]
# Prediction alone only adds uncertainty. Ten seconds of it, from a pose known exactly:

# %%
mu, sigma = np.zeros(3 + 2 * run.n_fiducials), np.zeros((3 + 2 * run.n_fiducials,) * 2)
mu[:3] = run.x0
for u in run.commands[:100]:
    mu, sigma = predict(mu, sigma, u, run.Q, dt=run.dt)
print("pose standard deviations after 10 s of prediction only:", np.round(np.sqrt(np.diag(sigma)[:3]), 3), "(m, m, rad)")
print("landmark block still zero:", np.all(sigma[3:, 3:] == 0))

# %% [markdown]
# ## 4. The expected observation and its Jacobian (Table 10.1, lines 14–21)
#
# With $\delta = m_j - (x, y)^T$ and $q = \delta^T \delta$:
#
# $$
# \hat z_j = \begin{pmatrix} \sqrt q \\ \operatorname{wrap}\big(\operatorname{atan2}(\delta_y, \delta_x) - \theta\big) \end{pmatrix}, \qquad
# H_j = \frac{1}{q} \begin{pmatrix} -\sqrt q\,\delta_x & -\sqrt q\,\delta_y & 0 & \sqrt q\,\delta_x & \sqrt q\,\delta_y \\ \delta_y & -\delta_x & -q & -\delta_y & \delta_x \end{pmatrix} F_{x,j}.
# $$
#
# The low-dimensional $2 \times 5$ Jacobian involves only the pose and landmark $j$; $F_{x,j}$ places its five columns into the full $2 \times (3 + 2K)$ matrix: columns 0–2 (the pose) and `3 + 2*j`, `4 + 2*j` (the landmark). Every other column is zero: one observation says nothing directly about the other landmarks.
#
# Accept `j` as one index (return shapes $(2,)$ and $(2, 3 + 2K)$) or an array of $k$ indices (shapes $(k, 2)$ and $(k, 2, 3 + 2K)$). A landmark estimated exactly at the robot's position has no bearing: raise a `ValueError`.

# %% tags=["exercise"]
def observation(mu, j):
    r"""Expected range and bearing of landmark(s) ``j`` and the Jacobian (Table 10.1, lines 14-21).

    With :math:`\delta = m_j - (x, y)^T` and :math:`q = \delta^T\delta`,

    .. math::

        \hat z = \begin{pmatrix} \sqrt q \\ \operatorname{wrap}(\operatorname{atan2}(\delta_y,
        \delta_x) - \theta) \end{pmatrix}, \qquad
        H = \frac{1}{q}\begin{pmatrix}
        -\sqrt q\,\delta_x & -\sqrt q\,\delta_y & 0 & \sqrt q\,\delta_x & \sqrt q\,\delta_y \\
        \delta_y & -\delta_x & -q & -\delta_y & \delta_x \end{pmatrix} F_{x,j},

    where :math:`F_{x,j}` places the five columns at the pose (0-2) and at the
    landmark (``3 + 2j``, ``4 + 2j``): every other column of the
    :math:`2 \times (3 + 2K)` Jacobian is zero.

    Parameters
    ----------
    mu : array_like, shape (3 + 2K,)
        State mean.
    j : int or array_like of int, shape (k,)
        Landmark index (or indices), ``0 <= j < K``.

    Returns
    -------
    z_hat : numpy.ndarray, shape (2,) or (k, 2)
        ``[range, bearing]``, bearing wrapped to ``[-pi, pi)``.
    H : numpy.ndarray, shape (2, 3 + 2K) or (k, 2, 3 + 2K)

    Raises
    ------
    ValueError
        A landmark estimate at the robot's position (range 0: no bearing, no Jacobian).
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_observation(observation)

# %% [markdown]
# Compare the Jacobian with central finite differences of $\hat z$ over the **whole** state, $\big(\hat z(\mu + \varepsilon e_i) - \hat z(\mu - \varepsilon e_i)\big) / 2\varepsilon$:

# %%
mu_test = np.array([1.0, -0.5, 0.7, -2.0, 3.0, 4.0, 1.0])
eps = 1e-6
numeric = np.column_stack([(observation(mu_test + eps * e, 1)[0] - observation(mu_test - eps * e, 1)[0]) / (2 * eps)
                           for e in np.eye(len(mu_test))])
print("analytic H:\n", np.round(observation(mu_test, 1)[1], 4))
print("largest difference from finite differences:", f"{np.abs(observation(mu_test, 1)[1] - numeric).max():.1e}")

# %% [markdown]
# ## 5. Correction (Table 10.1, lines 12–25)
#
# Stack the $k$ observations of one step (of landmarks already in the map) into one measurement of size $2k$: $\hat z$ and $H$ of `observation` row after row, and the noise $\operatorname{diag}(Q_t, \dots, Q_t)$. Then
#
# $$
# S = H \Sigma H^T + \operatorname{diag}(Q_t, \dots, Q_t), \qquad K = \Sigma H^T S^{-1}, \qquad e = z - \hat z, \qquad \mu' = \mu + K e, \qquad \Sigma' = \Sigma - K S K^T .
# $$
#
# * **Wrap the bearing innovations.** A bearing measured as $3.1$ rad and predicted as $-3.1$ rad differ by $0.08$ rad, not $6.2$. Wrap the corrected heading too.
# * **Keep $\Sigma$ symmetric positive definite.** $\Sigma - KSK^T$ equals the book's $(I - KH)\Sigma$ but is symmetric by construction; symmetrize once more against rounding, or use the Joseph form $(I - KH)\Sigma(I - KH)^T + K Q K^T$.
# * The book processes the observations one at a time, relinearizing after each. All at once, linearized at the predicted mean (the Freiburg course's choice), is what this lab asks; with one observation the two are the same.
# * No observation (an empty array or `None`): return the belief unchanged (as new arrays).
#
# Use `np.linalg.solve` rather than an explicit inverse.

# %% tags=["exercise"]
def correct(mu, sigma, observations, Qt):
    r"""EKF-SLAM correction with all of one step's observations at once (Table 10.1, lines 12-25).

    The k observations ``[r, phi, j]`` (landmarks already in the map) are
    stacked into one measurement of size 2k, linearized at the predicted mean
    (the book loops over them, relinearizing after each; with one observation,
    or a linear model, the two are the same):

    .. math::

        S = H \Sigma H^T + \operatorname{diag}(Q_t, \dots, Q_t), \quad
        K = \Sigma H^T S^{-1}, \quad e = z - \hat z \ (\text{bearings wrapped}),

    .. math::

        \mu' = \mu + K e, \qquad \Sigma' = \Sigma - K S K^T ,

    the last being :math:`(I - KH)\Sigma` written so that it is symmetric by
    construction (symmetrized once more against rounding). A bearing measured
    as 3.1 rad and predicted as -3.1 rad differ by 0.08 rad, not 6.2.

    Parameters
    ----------
    mu : array_like, shape (3 + 2K,)
    sigma : array_like, shape (3 + 2K, 3 + 2K)
    observations : array_like, shape (k, 3)
        Rows ``[range, bearing, id]``; ``k`` may be 0 (or ``None``): nothing changes.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance of one ``[range, bearing]`` (positive definite).

    Returns
    -------
    mu, sigma : numpy.ndarray
        New arrays; heading wrapped, ``sigma`` symmetric.

    Raises
    ------
    ValueError
        ``observations`` not of shape (k, 3), a landmark id outside ``0 <= id < K``,
        ``Qt`` not positive definite, or shapes of ``mu`` and ``sigma`` that do not
        fit.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_correct(correct)

# %% [markdown]
# ## 6. A new landmark (Table 10.1, lines 10–11)
#
# The first time landmark $j$ is seen, invert the measurement model for its mean:
#
# $$
# m_j = \begin{pmatrix} x + r \cos(\theta + \phi) \\ y + r \sin(\theta + \phi) \end{pmatrix}.
# $$
#
# The book then updates the landmark, starting from an infinite covariance, with that same observation. In the limit that update is the linearized propagation of the pose's and the measurement's uncertainty into the new landmark, with $G_x = \partial m_j / \partial x$ ($2 \times 3$) and $G_z = \partial m_j / \partial (r, \phi)$ ($2 \times 2$):
#
# $$
# \Sigma_{jj} = G_x \Sigma_{xx} G_x^T + G_z Q_t G_z^T, \qquad \Sigma_{j\,\cdot} = G_x\, \Sigma_{x\,\cdot} \;\; (\text{the pose's rows, every column but } j\text{'s}), \qquad \Sigma_{\cdot\,j} = \Sigma_{j\,\cdot}^T .
# $$
#
# The second term is the uncertainty of the measurement; the first, and the correlations, say that **the landmark is only as well known as the pose it was seen from**, and that its error is the pose's error. Whatever the rows and columns of $j$ held before is replaced.

# %% tags=["exercise"]
def add_landmark(mu, sigma, z, j, Qt):
    r"""Put landmark ``j`` into the map at its first sighting (Table 10.1, lines 10-11).

    The mean inverts the measurement model:
    :math:`m_j = (x + r\cos(\theta + \phi),\ y + r\sin(\theta + \phi))`.
    The covariance is the book's initialization with an infinite prior, in the
    limit, i.e. the linearized propagation of the pose's and the measurement's
    uncertainty, with :math:`G_x = \partial m_j / \partial x` (2 x 3) and
    :math:`G_z = \partial m_j / \partial z` (2 x 2):

    .. math::

        \Sigma_{jj} = G_x \Sigma_{xx} G_x^T + G_z Q_t G_z^T, \qquad
        \Sigma_{j\,\cdot} = G_x \Sigma_{x\,\cdot} \quad (\text{the pose's rows: every other
        entry}),

    and :math:`\Sigma_{\cdot\,j} = \Sigma_{j\,\cdot}^T`. Whatever rows and columns
    ``j`` held before are replaced. Cost O(K).

    Parameters
    ----------
    mu : array_like, shape (3 + 2K,)
    sigma : array_like, shape (3 + 2K, 3 + 2K)
    z : array_like, shape (2,)
        The first observation ``[range, bearing]`` of landmark ``j`` (range >= 0).
    j : int
        Landmark index, ``0 <= j < K``.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance.

    Returns
    -------
    mu, sigma : numpy.ndarray
        New arrays with landmark ``j`` filled in.

    Raises
    ------
    ValueError
        A ``z`` not of length 2 or with a negative range, ``j`` outside
        ``0 <= j < K``, or shapes of ``mu`` and ``sigma`` that do not fit.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_add_landmark(add_landmark)

# %% [markdown]
# ## 7. The whole run
#
# `ekf_slam` is the main loop. Each step: predict; correct with the observations of landmarks already in the map; then add the landmarks seen for the first time (so that a new landmark's first observation is used once, to place it). It also runs a Freiburg data set (section 9): there the commands are odometry $(r_1, t, r_2)$, the start is the origin, and the data carries no noise model, so `R` and `Qt` must be given.
#
# The only Python loops are over time steps and over the observations of one step; nothing loops over the landmarks of the state.

# %% tags=["exercise"]
def ekf_slam(robot_or_run, R=None, Qt=None, history=False):
    r"""Run EKF-SLAM over a whole run (Probabilistic Robotics Table 10.1).

    ::

        mu = (x0, 0, ..., 0); Sigma = 0       # the start pose defines the map's frame
        for each step:
            mu, Sigma = predict(mu, Sigma, command, R, dt, motion)
            mu, Sigma = correct(mu, Sigma, <observations of landmarks already in the map>, Qt)
            for each observation of a new landmark: mu, Sigma = add_landmark(mu, Sigma, z, j, Qt)

    A landmark seen twice in the step of its first sighting: the first row adds
    it, the others correct with it afterwards.

    Two kinds of run:

    - the fiducial robot (a :class:`robolab.fiducials.FiducialRobot`, driven from
      its current step, or a recorded :class:`robolab.fiducials.FiducialRun` or
      ``.npz`` path, replayed from its start): unicycle commands ``(v, omega)``
      with the robot's ``dt``, start at the robot's ``x0``, noise default the
      robot's own (``robot.Q``, ``robot.Qt``);
    - a :class:`robolab.datasets.FreiburgData` run: odometry ``(r1, t, r2)``
      (``motion="odometry"``), start at the origin, observation ids replaced by
      landmark rows (``data.indexed_observations(i)``); the data carries no
      noise model, so ``R`` and ``Qt`` must be given.

    Parameters
    ----------
    robot_or_run : FiducialRobot, FiducialRun, path or FreiburgData
    R : array_like, shape (3, 3), optional
        Motion noise covariance in the pose's coordinates.
    Qt : array_like, shape (2, 2), optional
        Measurement noise covariance.
    history : bool
        Also return the mean and covariance after every step.

    Returns
    -------
    dict
        ``path`` (T + 1, 3) pose estimates (row 0 is the start); ``landmarks`` (K, 2)
        and ``landmark_covs`` (K, 2, 2), NaN for a landmark never observed;
        ``observed`` (K,) bool; ``mu`` (3 + 2K,) and ``sigma`` the final belief;
        with ``history=True`` also ``means`` (T + 1, 3 + 2K) and ``covs``
        (T + 1, 3 + 2K, 3 + 2K).
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_ekf_slam(ekf_slam)

# %% [markdown]
# ### The map over time
#
# The run with `history=True` keeps the mean and covariance after every step. The map with $2\sigma$ ellipses (red: landmarks; blue: the robot's position) after 2, 8, 20 and 60 s:

# %%
result = ekf_slam(run, history=True)
landmark_error = np.hypot(*(result["landmarks"] - run.fiducials).T)
path_error = np.hypot(*(result["path"][:, :2] - run.true_poses[:, :2]).T)
print("fiducial errors [m]:", np.round(landmark_error, 3), f"  RMSE {np.sqrt(np.mean(landmark_error**2)):.3f} m")
print(f"final pose error {path_error[-1]:.3f} m (dead reckoning: {dr_error:.2f} m); largest along the path {path_error.max():.2f} m")

plot_ekf_slam_snapshots(result["means"], result["covs"], [20, 80, 200, 600], run.dt, run.true_poses, run.fiducials)
plt.show()

# %% [markdown]
# **Question.** Compare the figures with lab 07's FastSLAM map of the same run. Which landmark's ellipse is largest when it is first seen, and why? What happens to all the ellipses when the robot comes back to the first fiducials after 20 s?
#
# *Your answer here.*

# %% [markdown]
# ### The pose error against the truth
#
# The position error with the filter's own $2\sigma$ bound (top, log scale, with dead reckoning), and the heading error inside $\pm 2\sigma$ (bottom):

# %%
t = np.arange(run.n_steps + 1) * run.dt
plot_pose_errors(t, result["path"], run.true_poses, result["covs"][:, :3, :3], dead_reckoning=dead_reckoning)
plt.show()
inside = np.abs(wrap_angle(result["path"][1:, 2] - run.true_poses[1:, 2])) <= 2 * np.sqrt(result["covs"][1:, 2, 2])
print(f"the heading error is inside its 2-sigma bound at {100 * inside.mean():.0f} % of the steps")

# %% [markdown]
# ## 8. Why the correlations matter
#
# The correlation coefficients $\rho_{ab} = \Sigma_{ab} / \sqrt{\Sigma_{aa}\Sigma_{bb}}$ of the whole state after 2, 20 and 60 s (blank: not in the map yet):

# %%
plot_correlation_snapshots(result["covs"], [20, 200, 600], run.dt)
plt.show()
rho = correlation_matrix(result["covs"][-1])[3:, 3:]
off_block = ~np.kron(np.eye(run.n_fiducials, dtype=bool), np.ones((2, 2), dtype=bool))
print(f"after 60 s: mean |correlation| between coordinates of different landmarks {np.nanmean(np.abs(rho[off_block])):.2f}")

# %% [markdown]
# Landmarks seen from the same uncertain pose share that pose's error, so their estimates become correlated: the map may be off as a whole (shifted, rotated), but the landmarks' **relative** positions are known much better than their absolute ones. When the robot re-observes one landmark, the correction moves every correlated landmark with it.
#
# What if the filter threw the correlations away? Below, the same run with your functions, but after every step the cross-covariances between the pose and the landmarks and between different landmarks are set to zero (a "map of independent landmarks"). The normalized estimation error squared of the final state, $\text{NEES} = e^T \Sigma^{-1} e$ with $e = \mu - y_{\text{true}}$, should be about its dimension (13) for a filter whose covariance describes its errors:

# %%
def run_without_correlations(run):
    '''EKF-SLAM with every cross-covariance zeroed after each step (a deliberately wrong filter).'''
    k = run.n_fiducials
    mu, sigma, seen = np.zeros(3 + 2 * k), np.zeros((3 + 2 * k,) * 2), np.zeros(k, dtype=bool)
    mu[:3] = run.x0
    blocks = np.zeros((3 + 2 * k,) * 2, dtype=bool)  # the pose's block and each landmark's own
    blocks[:3, :3] = True
    blocks[3:, 3:] = np.kron(np.eye(k, dtype=bool), np.ones((2, 2), dtype=bool))
    replay = run.robot()
    while replay.run():
        mu, sigma = predict(mu, sigma, replay.input(), run.Q, dt=run.dt)
        z = replay.measurement()
        known = seen[z[:, 2].astype(int)]
        mu, sigma = correct(mu, sigma, z[known], run.Qt)
        for r, phi, j in z[~known]:
            mu, sigma = add_landmark(mu, sigma, [r, phi], int(j), run.Qt)
            seen[int(j)] = True
        sigma = np.where(blocks, sigma, 0.0)
    return mu, sigma

def nees(mu, sigma, run):
    e = mu - np.concatenate([run.true_poses[-1], run.fiducials.ravel()])
    e[2] = wrap_angle(e[2])
    return e @ np.linalg.solve(sigma, e)

mu_ind, sigma_ind = run_without_correlations(run)
for label, (m, s) in (("full EKF-SLAM", (result["mu"], result["sigma"])), ("correlations dropped", (mu_ind, sigma_ind))):
    err = np.hypot(*(m[3:].reshape(-1, 2) - run.fiducials).T)
    print(f"{label:>21}: landmark RMSE {np.sqrt(np.mean(err**2)):.3f} m, "
          f"mean landmark std {np.sqrt(np.diagonal(s)[3:]).mean():.3f} m, NEES {nees(m, s, run):.0f} (13 expected)")

# %% [markdown]
# **Question.** Explain with the correlation images and the numbers above why the correlations are what makes SLAM converge: what happens to the landmarks' correlations as the robot keeps observing them (Probabilistic Robotics section 10.2.4), why does re-observing one landmark improve the others, and what goes wrong when a filter treats the landmarks as independent of the pose and of each other?
#
# *Your answer here.*

# %% [markdown]
# ### The cost of one step
#
# How many entries of $\Sigma$ does one step change, as the map grows? Your `predict` and `correct` on maps of $K$ landmarks (one observation each):

# %%
ks = np.array([1, 3, 10, 30, 100, 300])
changed = {"predict": [], "correct (one observation)": []}
rng = np.random.default_rng(0)
for k in ks:
    n = 3 + 2 * k
    a = rng.normal(size=(n, n))
    sigma_k = a @ a.T / n + np.eye(n)
    mu_k = np.concatenate([[0.0, 0.0, 0.3], rng.uniform(1, 5, 2 * k)])
    changed["predict"].append(int(np.count_nonzero(predict(mu_k, sigma_k, [1.0, 0.1], run.Q, dt=0.1)[1] != sigma_k)))
    z = np.array([[3.0, 0.5, 0]])
    changed["correct (one observation)"].append(int(np.count_nonzero(correct(mu_k, sigma_k, z, run.Qt)[1] != sigma_k)))
plot_entries_changed(ks, changed, title="Covariance entries one step changes, against the map size")
plt.show()
print("entries changed by predict:", dict(zip(ks.tolist(), changed["predict"])))
print("entries changed by correct:", dict(zip(ks.tolist(), changed["correct (one observation)"])))

# %% [markdown]
# **Question.** The prediction changes $O(K)$ entries, one correction all $(3 + 2K)^2$ of them. What does one step of EKF-SLAM cost in time and memory as the map grows, and why is that a problem for a map of 10 000 landmarks? Compare with FastSLAM (lab 07: $M$ particles with $K$ small $2 \times 2$ filters each) and name one way around the quadratic cost (for example submaps, or the information form of section 12 of the book).
#
# *Your answer here.*

# %% [markdown]
# ## 9. Real data: the Freiburg course data set
#
# The Freiburg Robot Mapping course's range-bearing data (9 landmarks, 331 odometry steps $(r_1, t, r_2)$, known correspondences). It has no ground-truth path; the map is scored against the true landmark positions after the best SE(2) alignment (your map's frame is the start pose). The data set is not part of robolab: the cell says so when it is not on disk.

# %%
from robolab.datasets import locate, read_freiburg
from robolab.geometry import inverse, transform_points
from robolab.realdata.ekf_slam import MEASUREMENT_NOISE, MOTION_NOISE, run_ekf_slam_freiburg

folder = locate("freiburg_course")
if folder is None:
    print("The Freiburg data set is not on disk: robolab.datasets.fetch('freiburg_course') downloads it.")
else:
    freiburg = read_freiburg(folder)
    print("R =", np.diag(MOTION_NOISE).tolist(), " Qt =", np.diag(MEASUREMENT_NOISE).tolist(), "(diagonals)")
    real = run_ekf_slam_freiburg(freiburg, ekf_slam=ekf_slam, history=True)
    print(f"landmark RMSE {real['rmse']:.3f} m as estimated, {real['rmse_aligned']:.3f} m after SE(2) alignment")
    truth_in_map = transform_points(freiburg.landmarks, inverse(real["alignment"]))
    plot_ekf_slam_snapshots(real["means"], real["covs"], [10, 60, 331], 1.0, None, truth_in_map, unit="steps",
                            title="EKF-SLAM on the Freiburg data, true landmarks aligned to the map")
    plt.show()

# %% [markdown]
# ## 10. Report questions
#
# 1. Summarize EKF-SLAM with its equations (an overview): what is in the state, what each of your five functions does, and which blocks of $\Sigma$ each one changes.
#
#    *Your answer here.*
#
# 2. **EKF-SLAM against FastSLAM** on the same run. Which one gives the smaller map error here, what does each represent that the other does not (correlations, multiple path hypotheses), and which one would you choose for 10 landmarks, for 10 000, and for a robot whose heading error can grow large (linearization)?
#
#    *Your answer here.*
#
# 3. **Data association.** Every measurement here comes with its landmark's id. What would a wrong association do to an EKF-SLAM map, and why is it harder to recover from than in FastSLAM?
#
#    *Your answer here.*
