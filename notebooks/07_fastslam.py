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
#     lab: fastslam
# ---

# %% [markdown]
# # Lab 07 — FastSLAM 1.0 with known correspondences
#
# *Reference: Probabilistic Robotics (Thrun, Burgard, Fox), Chapter 13, **Table 13.1** (FastSLAM 1.0 with known correspondence, p. 450).*
#
# In the localization labs the map was given. Here the robot must build the map — the positions of five fiducials (visual markers with known identities) — **while** it localizes itself in that map. FastSLAM does it by factoring the SLAM posterior (eq. 13.8):
#
# $$
# p(x_{1:t}, m \mid z_{1:t}, u_{1:t}, c_{1:t}) \;=\; \underbrace{p(x_{1:t} \mid z_{1:t}, u_{1:t}, c_{1:t})}_{\text{particle filter over paths}}\;\prod_{j=1}^{K} \underbrace{p(m_j \mid x_{1:t}, z_{1:t}, c_{1:t})}_{\text{one 2-D EKF per landmark}}
# $$
#
# Given one particle's path, the landmarks are independent, so each particle carries $K$ small $2\times 2$ Kalman filters instead of one $2K \times 2K$ covariance.
#
# You will write, in order: `init_particles`, `predict_poses`, `h`, `h_jacobian`, `update_landmark`, `fastslam_step` and `fastslam`. After each exercise a check cell runs a quick test.
#
# Units: metres, radians, seconds. Angles are wrapped to $[-\pi, \pi)$ with `robolab.geometry.wrap_angle`.

# %%
import numpy as np
import matplotlib.pyplot as plt

from robolab.fiducials import DT, FiducialRobot, unicycle
from robolab.geometry import wrap_angle
from robolab.plotting import new_axes, plot_covariance_ellipse, plot_landmarks, plot_particles, plot_poses
from robolab.plotting.fastslam import (plot_error_vs_particles, plot_errors_over_time, plot_fastslam_map,
                                       plot_landmark_zooms, plot_particle_maps)
from robolab.checks import fastslam as checks

# %% [markdown]
# ## 1. The fiducial robot
#
# `FiducialRobot` plays the role of a simulated robot (`robolab.fiducials.FiducialRobot`). Drive it with
#
# ```python
# while robot.run():          # advance one step; False when the run is over
#     u = robot.input()       # the command [v, omega] of that step (m/s, rad/s)
#     z = robot.measurement() # (k, 3) rows [range, bearing, id] of the visible fiducials
# ```
#
# **Motion model** (the same as the localization lab), with Gaussian noise $w \sim \mathcal N(0, Q)$ every $\Delta t = 0.1$ s:
#
# $$
# \begin{pmatrix} x' \\ y' \\ \theta' \end{pmatrix} = \begin{pmatrix} x + v\,\Delta t\cos\theta \\ y + v\,\Delta t\sin\theta \\ \theta + \omega\,\Delta t \end{pmatrix} + w .
# $$
#
# **Measurement model**: for every fiducial within $0.5$–$5$ m and in the front half-plane (field of view $180^\circ$),
#
# $$
# z = \begin{pmatrix} r \\ \phi \end{pmatrix} = \begin{pmatrix} \sqrt{(m_x - x)^2 + (m_y - y)^2} \\ \operatorname{atan2}(m_y - y,\, m_x - x) - \theta \end{pmatrix} + v, \qquad v \sim \mathcal N(0, Q_t).
# $$
#
# The route is a rounded triangle driven three times (60 s, 600 steps), starting at $x_0 = [-2.5, -2, 0.25]^T$. The robot keeps the ground truth (`true_poses`, `fiducials`) for plots and grading — the filter never looks at it.

# %%
robot = FiducialRobot(seed=0)
run = robot.to_run()                     # the same run as plain arrays; run.robot() replays it
print(f"{run.n_steps} steps of {run.dt} s, {run.n_fiducials} fiducials, {len(run.measurements)} measurements")
print("Q  =", np.round(np.sqrt(np.diag(run.Q)), 4), "(standard deviations per step: m, m, rad)")
print("Qt =", np.round(np.sqrt(np.diag(run.Qt)), 4), "(standard deviations: m, rad)")

# dead reckoning: integrate the commands without any correction
dead_reckoning = [run.x0]
for u in run.commands:
    dead_reckoning.append(unicycle(dead_reckoning[-1], u, run.dt))
dead_reckoning = np.array(dead_reckoning)

ax = new_axes("The fiducial robot: true path and dead reckoning", figsize=(7, 6))
plot_poses(run.true_poses, ax, color="black", label="true path", arrows=False)
plot_poses(dead_reckoning, ax, color="tab:gray", label="dead reckoning", arrows=False, linestyle=":")
plot_landmarks(run.fiducials, ax, labels=True, color="black", label="fiducials")
ax.legend(loc="best", fontsize="small")
plt.show()
dr_error = np.hypot(*(dead_reckoning[-1, :2] - run.true_poses[-1, :2]))
print(f"dead reckoning ends {dr_error:.2f} m from the true final position")


# %% [markdown]
# ## 2. The particle set
#
# A MATLAB version would store the particles as cell arrays of structures (`X{j}.map{k}.mean`). In numpy we keep **arrays over all particles** so that every operation runs on all particles at once:
#
# | key | shape | meaning |
# |---|---|---|
# | `poses` | $(M, 3)$ | pose $x^{[k]}$ of particle $k$ |
# | `means` | $(M, K, 2)$ | landmark means $\mu^{[k]}_j$ — MATLAB's `X{k}.map{j}.mean` is `means[k, j]` |
# | `covs` | $(M, K, 2, 2)$ | landmark covariances $\Sigma^{[k]}_j$ |
# | `seen` | $(M, K)$, bool | landmark $j$ has a Gaussian belief in particle $k$ |
# | `weights` | $(M,)$ | importance weights, summing to one |
#
# Two ways to start a landmark:
#
# * **a vague prior** (`init="prior"`): $\mu_0 = 0$, $\Sigma_0 = 10^4 I$ for every landmark, so `seen` is all `True` and the first sighting is an ordinary EKF update from that vague prior;
# * **the book's first observation** (`init="first_observation"`, Table 13.1 lines 7–10): `seen` starts `False`; the first sighting sets $\mu = h^{-1}(z, x)$ and $\Sigma = H^{-1} Q_t H^{-T}$.
#
# Every particle starts at $x_0$: the map's frame is defined by the start pose.

# %% tags=["exercise"]
def init_particles(n_particles, n_landmarks, x0, init="prior"):
    r"""Create the initial FastSLAM particle set (Probabilistic Robotics, Table 13.1, line 1).

    Every particle starts at the known pose :math:`x_0` (SLAM fixes the map's
    frame by the start pose) with equal weight :math:`1/M`.

    ``init="prior"``: every landmark has the vague Gaussian belief
    :math:`\mu_0 = 0`, :math:`\Sigma_0 = 10^4 I`, so ``seen`` is all True and the
    first observation is an ordinary EKF update from that prior.

    ``init="first_observation"`` (the book, Table 13.1 lines 7-10): no landmark
    has a belief yet (``seen`` all False; ``means`` and ``covs`` hold the
    placeholders 0 and :math:`10^4 I`); the first observation of landmark j
    initializes it by inverting the measurement model,
    :math:`\mu = h^{-1}(z, x)`, :math:`\Sigma = H^{-1} Q_t H^{-T}`.

    Parameters
    ----------
    n_particles : int
        Number of particles M >= 1.
    n_landmarks : int
        Number of landmarks K >= 1.
    x0 : array_like, shape (3,)
        Start pose ``(x, y, theta)``.
    init : {"prior", "first_observation"}
        How landmarks start (see above).

    Returns
    -------
    dict of numpy arrays
        ``poses`` (M, 3), ``means`` (M, K, 2), ``covs`` (M, K, 2, 2),
        ``seen`` (M, K) bool, ``weights`` (M,); every array is its own copy.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_init_particles(init_particles)


# %% [markdown]
# ## 3. Sampling the motion (Table 13.1, line 4)
#
# Each particle draws its own noisy successor pose $x_t^{[k]} \sim p(x_t \mid x_{t-1}^{[k]}, u_t)$ from the model of section 1. Draw correlated noise with a square root of $Q$ (e.g. a Cholesky factor or `rng.multivariate_normal`), never with $Q$ itself as a standard deviation.

# %% tags=["exercise"]
def predict_poses(poses, command, Q, rng, dt=DT):
    r"""Sample every particle's next pose from the lab's motion model (Table 13.1, line 4).

    The fiducial robot's unicycle model with additive Gaussian pose noise
    (the same model :mod:`robolab.fiducials` simulates):

    .. math::

        \begin{pmatrix} x' \\ y' \\ \theta' \end{pmatrix} =
        \begin{pmatrix} x + v\,\Delta t \cos\theta \\ y + v\,\Delta t \sin\theta \\
        \theta + \omega\,\Delta t \end{pmatrix} + w, \qquad w \sim \mathcal N(0, Q),

    independently for each particle, with :math:`\theta'` wrapped to
    :math:`[-\pi, \pi)`.

    Parameters
    ----------
    poses : array_like, shape (M, 3)
        Particle poses; not modified.
    command : array_like, shape (2,)
        ``[v, omega]`` in m/s and rad/s.
    Q : array_like, shape (3, 3)
        Symmetric positive semi-definite noise covariance per step (zeros: no noise).
    rng : numpy.random.Generator
        Source of the noise.
    dt : float
        Time step in seconds.

    Returns
    -------
    numpy.ndarray, shape (M, 3)
        The sampled poses, a new array.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_predict_poses(predict_poses)

# %% [markdown]
# Without measurements the particle cloud only spreads. Here are 200 particles after 10 s of prediction alone:

# %%
rng = np.random.default_rng(1)
cloud = np.tile(run.x0, (200, 1))
for u in run.commands[:100]:
    cloud = predict_poses(cloud, u, run.Q, rng, dt=run.dt)
ax = new_axes("Prediction only: 200 particles after 10 s", figsize=(6, 5))
plot_poses(run.true_poses[:101], ax, color="black", label="true path (0-10 s)", arrows=False)
plot_particles(cloud, ax=ax, label="particles at 10 s")
ax.legend(loc="best", fontsize="small")
plt.show()
print("spread of the cloud (std of x, y in m, theta in rad):", np.round(cloud.std(axis=0), 3))


# %% [markdown]
# ## 4. The measurement model and its Jacobian
#
# With $\delta = \mu_j - (x, y)^T$ and $q = \delta^T \delta$ (Probabilistic Robotics eq. 6.40 and 13.11):
#
# $$
# \hat z = h(\mu_j, x) = \begin{pmatrix} \sqrt q \\ \operatorname{wrap}\big(\operatorname{atan2}(\delta_y, \delta_x) - \theta\big) \end{pmatrix},
# \qquad
# H = \frac{\partial h}{\partial \mu_j} = \begin{pmatrix} \delta_x/\sqrt q & \delta_y/\sqrt q \\ -\delta_y/q & \delta_x/q \end{pmatrix}.
# $$
#
# The bearing row: $\partial\phi/\partial\mu_{j,x} = (y - \mu_y)/q$ and $\partial\phi/\partial\mu_{j,y} = (\mu_x - x)/q$. FastSLAM only needs the Jacobian with respect to the **landmark**: the pose is not a Kalman state, it is sampled.
#
# Write both vectorized over leading dimensions (for example `landmark` of shape $(M, 2)$ and `pose` $(M, 3)$).

# %% tags=["exercise"]
def h(landmark, pose):
    r"""Range-bearing measurement :math:`\hat z = h(\mu_j, x)` (Probabilistic Robotics eq. 6.40).

    .. math::

        \hat r = \sqrt{(\mu_x - x)^2 + (\mu_y - y)^2}, \qquad
        \hat\phi = \operatorname{wrap}\big(\operatorname{atan2}(\mu_y - y, \mu_x - x) - \theta\big)

    Broadcasts over leading dimensions (for example ``landmark`` (M, 2) and
    ``pose`` (M, 3) for all particles at once).

    Parameters
    ----------
    landmark : array_like, shape (..., 2)
        Landmark position(s) :math:`\mu_j`, metres.
    pose : array_like, shape (..., 3)
        Robot pose(s) ``(x, y, theta)``.

    Returns
    -------
    numpy.ndarray, shape (..., 2)
        ``[range, bearing]``; bearing wrapped to ``[-pi, pi)``.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_h(h)


# %% tags=["exercise"]
def h_jacobian(landmark, pose):
    r"""Jacobian :math:`H = \partial h(\mu_j, x) / \partial \mu_j` with respect to the landmark.

    With :math:`\delta = \mu_j - (x, y)^T` and :math:`q = \delta^T\delta`
    (Probabilistic Robotics eq. 13.11 restricted to the landmark; the
    hints give the bearing row):

    .. math::

        H = \begin{pmatrix} \delta_x / \sqrt q & \delta_y / \sqrt q \\
                            -\delta_y / q & \delta_x / q \end{pmatrix}

    :math:`q` is floored at a tiny positive value (say :math:`10^{-12}`) so
    that a landmark estimate on top of the robot gives a large but finite Jacobian.

    Parameters
    ----------
    landmark : array_like, shape (..., 2)
    pose : array_like, shape (..., 3)

    Returns
    -------
    numpy.ndarray, shape (..., 2, 2)
        Row 0 is the range's gradient, row 1 the bearing's.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_h_jacobian(h_jacobian)

# %% [markdown]
# A Jacobian is easy to get wrong by a sign or a transposition; compare it with central finite differences $\big(h(\mu + \varepsilon e_i) - h(\mu - \varepsilon e_i)\big) / 2\varepsilon$:

# %%
pose, landmark, eps = np.array([1.0, -0.5, 0.7]), np.array([-2.0, 3.0]), 1e-6
numeric = np.column_stack([(h(landmark + eps * e, pose) - h(landmark - eps * e, pose)) / (2 * eps) for e in np.eye(2)])
print("analytic:\n", h_jacobian(landmark, pose))
print("finite differences:\n", numeric)
print("largest difference:", np.abs(h_jacobian(landmark, pose) - numeric).max())


# %% [markdown]
# ## 5. One small EKF per landmark (Table 13.1, lines 12–19)
#
# For an observed landmark with belief $\mathcal N(\mu, \Sigma)$, seen from pose $x$:
#
# $$
# \hat z = h(\mu, x), \quad Q = H \Sigma H^T + Q_t, \quad K = \Sigma H^T Q^{-1}, \quad e = z - \hat z,
# $$
# $$
# \mu' = \mu + K e, \qquad \Sigma' = (I - K H)\,\Sigma, \qquad w = |2\pi Q|^{-1/2} \exp\!\big(-\tfrac12\, e^T Q^{-1} e\big).
# $$
#
# **Two typos that circulate in write-ups of this algorithm.** One version defines $e = \hat z - z$ and then adds $K e$ — that moves the landmark *away* from the measurement; the innovation is $e = z - \hat z$. And it prints the weight as $|2\pi Q|^{+1/2}\exp(-\frac12 e^T Q e)$; the Gaussian density has the determinant to the power $-\frac12$ and the **inverse** $Q^{-1}$ in the exponent. With that version, particles that predict the measurement badly are not penalized, and the filter degrades to dead reckoning.
#
# **The bearing wrap.** A bearing measured as $3.1$ rad and predicted as $-3.1$ rad differ by $0.08$ rad, not $6.2$: wrap the second component of $e$ to $[-\pi, \pi)$ with `wrap_angle`.
#
# **Return the log-likelihood** $\ln w = -\frac12 \ln|2\pi Q| - \frac12 e^T Q^{-1} e$. For a landmark estimate a few metres off, $w$ is below $10^{-300}$ and underflows to $0$ in every particle; the logarithm stays finite.

# %% tags=["exercise"]
def update_landmark(mean, cov, z, pose, Qt):
    r"""EKF update of one landmark's Gaussian, and the log-likelihood (Table 13.1, lines 12-19).

    .. math::

        \hat z &= h(\mu, x), \quad H = \partial h / \partial \mu, \quad
        Q = H \Sigma H^T + Q_t, \quad K = \Sigma H^T Q^{-1} \\
        e &= z - \hat z \quad (\text{bearing wrapped to } [-\pi, \pi)) \\
        \mu' &= \mu + K e, \qquad \Sigma' = (I - K H)\,\Sigma \\
        \ln w &= -\tfrac12 \ln|2\pi Q| - \tfrac12 e^T Q^{-1} e

    so :math:`w = |2\pi Q|^{-1/2}\exp(-\frac12 e^T Q^{-1} e)`, the Gaussian
    density of the innovation. Some write-ups print
    :math:`|2\pi Q|^{+1/2}\exp(-\frac12 e^T Q e)` and :math:`e = \hat z - z`:
    both are typos. Without the wrap, a bearing measured as 3.1 rad and predicted
    as -3.1 rad (0.08 rad apart) would look 6.2 rad apart.

    The likelihood is returned as its logarithm: for a landmark estimate metres
    away from the measurement it is :math:`e^{-1000}` or less, which underflows
    to 0 in every particle; the log stays finite and the filter normalizes
    with the log-sum-exp trick.

    Broadcasts over leading dimensions, e.g. ``mean`` (M, 2), ``cov``
    (M, 2, 2), ``pose`` (M, 3) and one ``z`` (2,) for all particles.

    Parameters
    ----------
    mean : array_like, shape (..., 2)
        Landmark mean :math:`\mu`, metres.
    cov : array_like, shape (..., 2, 2)
        Landmark covariance :math:`\Sigma` (symmetric positive definite).
    z : array_like, shape (..., 2)
        Measurement ``[range, bearing]``.
    pose : array_like, shape (..., 3)
        The particle's pose.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance.

    Returns
    -------
    mean : numpy.ndarray, shape (..., 2)
    cov : numpy.ndarray, shape (..., 2, 2)
        Symmetrized.
    log_likelihood : numpy.ndarray, shape (...)
        :math:`\ln \mathcal N(z; \hat z, Q)`, finite.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_update_landmark(update_landmark)

# %% [markdown]
# Why the book initializes a landmark from its first observation: below, the robot sees fiducial 4 for the first time. The vague prior $\mathcal N(0, 10^4 I)$ linearizes $h$ at the origin, so its first EKF step is one Gauss-Newton step from $(0, 0)$ — and it leaves the landmark far from the truth with a small, confident covariance. Inverting $h$ puts it where it was seen.

# %%
t0 = int(run.measurements[run.measurements[:, 3] == 4][0, 0])      # first step that sees fiducial 4
z0 = run.observations(t0)
z0 = z0[z0[:, 2] == 4][0, :2]
pose0 = run.true_poses[t0 + 1]
mean_prior, cov_prior, _ = update_landmark(np.zeros(2), 1e4 * np.eye(2), z0, pose0, run.Qt)
angle = pose0[2] + z0[1]
mean_first = pose0[:2] + z0[0] * np.array([np.cos(angle), np.sin(angle)])
H0 = h_jacobian(mean_first, pose0)
cov_first = np.linalg.inv(H0) @ run.Qt @ np.linalg.inv(H0).T

ax = new_axes("First sighting of fiducial 4: vague prior vs first-observation init", figsize=(7, 5.5))
plot_poses(pose0, ax, color="black", label="robot (true pose)", path=False, arrow_length=0.6)
plot_landmarks(run.fiducials[4:5], ax, labels=["4"], color="black", label="true fiducial 4")
for mean, cov, color, label in ((mean_prior, cov_prior, "tab:red", "after one update from N(0, 1e4 I)"),
                                (mean_first, cov_first, "tab:green", "h^-1(z, x), H^-1 Qt H^-T")):
    ax.scatter(*mean, marker="x", color=color, label=label)
    plot_covariance_ellipse(mean, cov, ax, n_std=3.0, edgecolor=color)
ax.scatter(0, 0, marker="o", color="tab:red", facecolor="none", label="the prior's mean (origin)")
ax.legend(loc="lower left", fontsize="small")
plt.show()
for name, mean in (("prior", mean_prior), ("first observation", mean_first)):
    print(f"{name:>18}: {np.hypot(*(mean - run.fiducials[4])):.2f} m from the true fiducial")


# %% [markdown]
# ## 6. The FastSLAM step (Table 13.1)
#
# For every particle $k$ at once:
#
# 1. sample $x_t^{[k]}$ with `predict_poses`;
# 2. for every observation $[r, \phi, j]$: if landmark $j$ has a belief in particle $k$, update it with `update_landmark` and add the log-likelihood to $\ell^{[k]}$; otherwise initialize it from the observation (lines 7–9) with the constant factor $p_0$ ($\ln p_0 = 0$ here: all particles see the same new landmark, so it cancels);
# 3. normalize in log space (the *log-sum-exp* trick): $\;w^{[k]} = \exp(\ell^{[k]} - \max_i \ell^{[i]}) \,/\, \sum_i \exp(\ell^{[i]} - \max_i \ell^{[i]})$;
# 4. resample with the low-variance sampler (Table 4.4, from lab 03, given below).
#
# Use `update_landmark` on arrays of shape $(M, b, \cdot)$ to update the $b$ observed landmarks of all $M$ particles in one call (indexing `means[:, ids]`). **No loop over particles.**
#
# **Aliasing.** In MATLAB, `Y{i} = X{j}` copies. In Python, a list of per-particle dicts resampled with `[X[j] for j in idx]` makes two particles share *one* map: updating one updates the other. With arrays, fancy indexing `means[idx]` makes a copy. Also return new arrays rather than modifying the `state` you were given.

# %%
def _low_variance_resample(weights, rng):
    '''Indices drawn by the low-variance sampler (Probabilistic Robotics Table 4.4), given.'''
    m = len(weights)
    pointers = rng.uniform(0.0, 1.0 / m) + np.arange(m) / m
    return np.minimum(np.searchsorted(np.cumsum(weights), pointers, side="left"), m - 1)


# %% tags=["exercise"]
def fastslam_step(state, command, observations, Q, Qt, rng, dt=DT, resample=True):
    r"""One step of FastSLAM 1.0 with known correspondences (Probabilistic Robotics Table 13.1).

    1. Sample each particle's pose from the motion model (:func:`predict_poses`).
    2. For every observation ``[r, phi, j]``, in every particle at once: if
       landmark j has a belief, EKF-update it (:func:`update_landmark`) and
       multiply the weight by the likelihood; otherwise initialize it from the
       observation, :math:`\mu = (x + r\cos(\theta+\phi), y + r\sin(\theta+\phi))`,
       :math:`\Sigma = H^{-1} Q_t H^{-T}`, weight factor :math:`p_0`. Landmarks not
       observed are left alone. Observations of different landmarks are
       processed together; a repeated id waits for the next round.
    3. Normalize the weights in log space:
       :math:`w_k = \exp(\ell_k - \max\ell) / \sum_i \exp(\ell_i - \max\ell)` with
       :math:`\ell_k = \ln w_k^{old} + \sum \ln \mathcal N(z; \hat z, Q)`, so the
       weights stay finite even when every likelihood underflows.
    4. Resample with the low-variance sampler (Table 4.4), unless ``resample``
       is False or there was no observation (then the weights did not change).
       Resampling copies the chosen particles' arrays (fancy indexing): no two
       particles share landmark memory, and the input ``state`` is not modified.

    Parameters
    ----------
    state : dict
        ``poses``, ``means``, ``covs``, ``seen``, ``weights`` as made by
        :func:`init_particles`.
    command : array_like, shape (2,)
        ``[v, omega]``.
    observations : array_like, shape (k, 3)
        Rows ``[range, bearing, id]`` (``k`` may be 0; ``None`` means none).
    Q : array_like, shape (3, 3)
        Motion noise covariance.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance.
    rng : numpy.random.Generator
    dt : float
        Time step in seconds.
    resample : bool or float
        True (default): resample after every step with an observation, as the
        book. False: never; the new state keeps the normalized importance
        weights. A number in (0, 1]: resample only when
        :math:`N_{eff} <` ``resample * M`` (0.5: below half the particles).

    Returns
    -------
    dict
        The new state (new arrays). After resampling the weights are uniform.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_fastslam_step(fastslam_step)


# %% [markdown]
# ## 7. The whole run
#
# `fastslam` is the main loop: initialize, then `while robot.run(): ...`. Report the path (the mean of the particles after every step) and the final map: the weighted mixture of the particles' landmark Gaussians, $\bar\mu_j = \sum_k w_k \mu^{[k]}_j$ and $\bar\Sigma_j = \sum_k w_k\big(\Sigma^{[k]}_j + (\mu^{[k]}_j - \bar\mu_j)(\mu^{[k]}_j - \bar\mu_j)^T\big)$.

# %% tags=["exercise"]
def fastslam(
    robot_or_run, n_particles, rng, init="first_observation", Q=None, Qt=None, history=False
):
    r"""Run FastSLAM 1.0 over a whole run of the fiducial robot (Probabilistic Robotics, Table 13.1).

    ::

        state = init_particles(M, K, x0, init)
        while robot.run():
            state = fastslam_step(state, robot.input(), robot.measurement(), Q, Qt, rng)

    Estimates reported (document of choice): the pose estimate at each step is
    the mean of the particles after the step (after resampling all weights are
    equal; the heading is the circular mean). The final map is the weighted
    mixture of the particles' landmark Gaussians, moment-matched:
    :math:`\bar\mu_j = \sum_k w_k \mu_{k,j}`,
    :math:`\bar\Sigma_j = \sum_k w_k (\Sigma_{k,j} + (\mu_{k,j}-\bar\mu_j)(\mu_{k,j}-\bar\mu_j)^T)`.
    Landmarks never observed are reported as NaN.

    Parameters
    ----------
    robot_or_run : FiducialRobot, FiducialRun or path
        A :class:`robolab.fiducials.FiducialRobot` (driven from its current
        step), or a recorded :class:`robolab.fiducials.FiducialRun` / ``.npz``
        path (replayed from its start).
    n_particles : int
        Number of particles M.
    rng : numpy.random.Generator
    init : {"first_observation", "prior"}
        Landmark initialization (:func:`init_particles`). The default is the
        book's: ``"prior"`` linearizes the first update of every
        landmark at the origin, which can leave it metres off with a small
        covariance for hundreds of steps (the notebook shows it).
    Q, Qt : array_like, optional
        Noise covariances the filter assumes; default the robot's own.
    history : bool
        Also return every particle's pose at every step.

    Returns
    -------
    dict
        ``path`` (T+1, 3) estimated poses (row 0 is ``x0``); ``landmarks`` (K, 2);
        ``landmark_covs`` (K, 2, 2); ``observed`` (K,) bool; ``state`` the final
        particle set; with ``history=True`` also ``particles`` (T+1, M, 3).
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_fastslam(fastslam)

# %% [markdown]
# ### The report figure
#
# Estimated fiducials with their $2\sigma$ covariance ellipses, the true ones, and the estimated and true paths (100 particles):

# %%
result = fastslam(run, 100, np.random.default_rng(0))
landmark_error = np.hypot(*(result["landmarks"] - run.fiducials).T)
path_error = np.hypot(*(result["path"][:, :2] - run.true_poses[:, :2]).T)
print("fiducial errors [m]:", np.round(landmark_error, 3), f"  RMSE {np.sqrt(np.mean(landmark_error**2)):.3f} m")
print(f"final pose error {path_error[-1]:.3f} m (dead reckoning: {dr_error:.2f} m)")

plot_fastslam_map(run.true_poses, run.fiducials, result["path"], result["landmarks"], result["landmark_covs"],
                  dead_reckoning=dead_reckoning, title="FastSLAM (M = 100): fiducials and paths")
plt.show()

# %% [markdown]
# The same filter replayed, every 20th step: watch the particle cloud spread between sightings and the
# fiducials appear on the map as they are first seen (the replay reruns *your* `fastslam_step`, 50 particles).

# %%
from robolab.plotting.animation import animate_fastslam, replay_fastslam, show_animation

replay = replay_fastslam(run, init_particles, fastslam_step, 50, np.random.default_rng(0), every=20)
show_animation(animate_fastslam(replay))

# %% [markdown]
# At this scale the $2\sigma$ ellipses are hardly visible. Up close, $\pm 0.5$ m around each true fiducial:

# %%
plot_landmark_zooms(run.fiducials, result["landmarks"], result["landmark_covs"], result["state"]["means"])
plt.show()


# %% [markdown]
# **Question.** Are the ellipses consistent with the actual errors (would the true fiducial fall inside a $2\sigma$ ellipse about 86 % of the time)? Keep your answer in mind for section 8.1.
#
# *Your answer here.*

# %% [markdown]
# ### A vague prior against the book's first-observation initialization
#
# The same run and the same random seed, once with each initialization; the error of the map (over the fiducials seen so far) after every step:

# %%
def track_errors(init, n_particles=50, seed=0):
    '''Landmark RMSE over the fiducials seen so far, and pose error, after every step.'''
    rng = np.random.default_rng(seed)
    replay = run.robot()
    state = init_particles(n_particles, run.n_fiducials, run.x0, init=init)
    observed = np.zeros(run.n_fiducials, dtype=bool)
    lm_err, pose_err = [], []
    while replay.run():
        z = replay.measurement()
        observed[z[:, 2].astype(int)] = True
        state = fastslam_step(state, replay.input(), z, run.Q, run.Qt, rng, dt=run.dt)
        estimate = np.einsum("k,kjd->jd", state["weights"], state["means"])
        err = np.hypot(*(estimate - run.fiducials).T)[observed]
        lm_err.append(np.sqrt(np.mean(err**2)) if err.size else np.nan)
        pose_err.append(np.hypot(*(state["weights"] @ state["poses"][:, :2] - replay.pose[:2])))
    return np.array(lm_err), np.array(pose_err)

t = np.arange(1, run.n_steps + 1) * run.dt
errors = {init: track_errors(init) for init in ("prior", "first_observation")}
plot_errors_over_time(t, {f"landmark RMSE, init={k}": v[0] for k, v in errors.items()},
                      title="Map error: vague prior vs first-observation init (M = 50)", ylabel="landmark RMSE [m]")
plt.show()
for init, (lm_err, pose_err) in errors.items():
    print(f"{init:>18}: final landmark RMSE {lm_err[-1]:.2f} m, final pose error {pose_err[-1]:.2f} m")

# %% [markdown]
# ## 7.2 Real data: the Freiburg data set, and resampling only when needed
#
# The Freiburg Robot Mapping course's range-bearing data (9 landmarks, 331 steps of odometry `(r1, t, r2)`; one
# odometry step is two of your unicycle steps). Resampling after every measurement throws away particles nearly as
# good as the kept ones; resampling only when the effective sample size $N_{eff} = 1 / \sum_k w_k^2$ falls below
# $M/2$ keeps them. Give your `fastslam_step` that option: `resample=0.5` (a fraction instead of `True`) means
# "resample when $N_{eff} < 0.5 M$". The data set is not part of robolab; the cell says so when it is not on disk.

# %%
from robolab.datasets import locate, read_freiburg
from robolab.realdata.fastslam import run_fastslam_freiburg

folder = locate("freiburg_course")
if folder is None:
    print("The Freiburg data set is not on disk: robolab.datasets.fetch('freiburg_course') downloads it.")
else:
    freiburg = read_freiburg(folder)
    for label, ess in (("every step", None), ("N_eff < M/2", 0.5)):
        res = run_fastslam_freiburg(freiburg, 100, np.random.default_rng(0), fastslam_step=fastslam_step,
                                    init_particles=init_particles, ess_threshold=ess)
        print(f"resampling {label}: {res['resamples']} resamplings, landmark RMSE {res['rmse']:.3f} m "
              f"({res['rmse_aligned']:.3f} m after SE(2) alignment)")

# %% [markdown]
# ## 8. Report questions
#
# ### 8.1 A particle filter and many small EKFs
#
# Each particle is a hypothesis about the robot's **path**; conditioned on that path, every landmark gets its own $2 \times 2$ EKF. With $M$ particles and $K$ landmarks that is $M \cdot K$ independent Kalman filters, and the particle filter decides which of them survive through the weights $w = \prod \mathcal N(z; \hat z, Q)$. Below: shortly after fiducial 2 is first seen, the particles' poses and eight particles' EKFs for fiducial 2; then the spread of the landmark means *across* particles compared with the size of one particle's own EKF, now and at the end of the run:

# %%
# replay the run with 100 particles until 1 s after fiducial 2 is first seen
t_new = int(run.measurements[run.measurements[:, 3] == 2][0, 0])
rng = np.random.default_rng(0)
replay = run.robot()
state = init_particles(100, run.n_fiducials, run.x0, init="first_observation")
for _ in range(t_new + 11):
    replay.run()
    state = fastslam_step(state, replay.input(), replay.measurement(), run.Q, run.Qt, rng, dt=run.dt)

ax = new_axes(f"Fiducial 2 in 8 particles' maps, {(t_new + 11) * run.dt:.1f} s into the run", figsize=(7, 5.5))
plot_particles(state["poses"], ax=ax, label="particles (poses)")
plot_particle_maps(state["means"], state["covs"], particles=range(0, 100, 13), ax=ax, landmarks=[2], seen=state["seen"])
plot_landmarks(run.fiducials[2:3], ax, labels=["2"], color="black", label="true fiducial 2", size=120)
plot_poses(replay.pose, ax, color="black", path=False, arrow_length=0.5, label="true pose")
ax.legend(loc="best", fontsize="x-small")
plt.show()

def spread_and_size(state, j):
    '''Spread of landmark j's mean across particles, and one particle's EKF standard deviation (m).'''
    between = np.sqrt(np.var(state["means"][:, j], axis=0).sum())
    within = np.sqrt(np.trace(state["covs"][:, j], axis1=1, axis2=2).mean())
    return between, within

final = result["state"]
print("fiducial 2 now:        spread across particles %.3f m, one EKF's std %.3f m" % spread_and_size(state, 2))
print("fiducial 2 at the end: spread across particles %.3f m, one EKF's std %.3f m" % spread_and_size(final, 2))
print("distinct particles after the last resampling:", len(np.unique(final["poses"], axis=0)), "of", len(final["poses"]))
print("distinct fiducial-2 maps at the end:", len(np.unique(final["means"][:, 2], axis=0)))

# %% [markdown]
# **Question.** Explain, with the figure and the numbers above, how FastSLAM combines a particle filter and extended Kalman filters. What does each part estimate, what does the weight of a particle measure, and why is a $2\times 2$ EKF per landmark enough (compare with EKF SLAM's $(3 + 2K)$-dimensional Gaussian)? The map's uncertainty is the spread across particles *plus* each EKF's covariance: after many resamplings, how many distinct path histories are left, and what does that do to the reported uncertainty?
#
# *Your answer here.*
#
# ### 8.2 Why SLAM is hard: loop closure
#
# While the robot drives through parts of the loop where it sees only landmarks it has just mapped, its pose error can only grow; when it sees again the fiducials mapped at the start (about every 20 s, when the loop closes), the error of the whole path is pulled back.

# %%
plot_errors_over_time(t, {"FastSLAM (M = 100)": path_error[1:],
                          "dead reckoning": np.hypot(*(dead_reckoning[1:, :2] - run.true_poses[1:, :2]).T)},
                      events=[20.0, 40.0], title="Position error along the run (loop closes every 20 s)", ylabel="position error [m]")
plt.show()

# %% [markdown]
# ### 8.3 Why SLAM is hard: particle depletion
#
# Resampling throws particles away. With few particles, the filter soon has no particle near the true path, and — because a particle's map is tied to its path — no good map either. Each setting runs twice, with different random seeds (the band spans the two runs):

# %%
n_particles = np.array([1, 3, 10, 30, 100])
sweep = np.zeros((len(n_particles), 2, 2))
for a, m in enumerate(n_particles):
    for s in range(2):
        out = fastslam(run, int(m), np.random.default_rng(100 + s))
        sweep[a, s, 0] = np.sqrt(np.nanmean(np.sum((out["landmarks"] - run.fiducials) ** 2, axis=1)))
        sweep[a, s, 1] = np.hypot(*(out["path"][-1, :2] - run.true_poses[-1, :2]))
plot_error_vs_particles(n_particles, sweep, title="Particle depletion: error against the number of particles")
plt.show()
print("landmark RMSE [m] per M, mean of the two runs:",
      dict(zip(n_particles.tolist(), np.round(np.mean(sweep[:, :, 0], 1), 3).tolist())))

# %% [markdown]
# **Questions.**
#
# 1. Using the three figures of this section, give reasons why simultaneous localization and mapping is difficult: the coupling of pose and map errors, loop closure, and particle depletion as $M$ drops. Where does the curve of error against $M$ flatten, and why does one particle (a single EKF-like hypothesis) still beat dead reckoning?
#
#    *Your answer here.*
#
# 2. **Data association.** This lab gives every measurement its fiducial's id (known correspondence, $c_t$). What would go wrong if two fiducials looked alike, and how does FastSLAM 2.0 / per-particle data association (Probabilistic Robotics section 13.5) deal with it?
#
#    *Your answer here.*
#
# 3. The vague prior initializes every landmark at $\mu_0 = 0$ with $\Sigma_0 = 10^4 I$. Explain, with the figures of sections 5 and 7, why the book's initialization from the first observation gives a better map, and when the vague prior would be harmless.
#
#    *Your answer here.*
#
# 4. Summarize the method with its equations (an overview), and state the two typos of section 5 (the innovation's sign and the weight's formula) with their corrections.
#
#    *Your answer here.*
