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
#     lab: landmark_pf
# ---

# %% [markdown]
# # Lab 03 — A particle filter in the landmark world
#
# A robot drives through a **cyclic** 100 m x 100 m world (leave it on the right, come back on the left)
# with four landmarks. It knows its commands, which are noisy, and it measures its **range to every landmark**,
# also noisily. You will localize it with a **particle filter** (Probabilistic Robotics, Table 4.3) and
# **low-variance resampling** (Table 4.4), step by step (sections a to g below), and then
# find out where the filter breaks.
#
# Everything you implement works on **all particles at once**: particles are an `(N, 3)` array of poses
# $(x, y, \theta)$. A Python `for` loop over particles is a bug here (it is ~100 times slower).
#
# Randomness always comes from a `numpy.random.Generator` argument `rng`, so every run is reproducible.
#
# Conventions: headings are wrapped to $[-\pi, \pi)$ with `wrap_angle`, positions to $[0, 100)$ with
# `wrap_position`; both are imported below and you may use them.

# %%
import numpy as np
import matplotlib.pyplot as plt

from robolab.geometry import wrap_angle
from robolab.world import LANDMARKS, cRobot, cWorld, wrap_position
from robolab.plotting.landmark_pf import (plot_count_variance, plot_deprivation, plot_error_vs_particles,
                                          plot_filter_run, plot_paths, plot_world_and_robots)
from robolab.checks import landmark_pf as checks

SEED = 2024  # one random seed for the whole notebook: rerunning gives the same figures

# %% [markdown]
# ## a. The world and the robot
#
# `cWorld()` holds the landmarks (robolab uses the classic layout
# $(20, 20), (80, 80), (20, 80), (80, 20)$). `cRobot(rng=...)` is one robot with a pose and noise parameters;
# `set(x, y, theta)` places it (x and y must lie in $[0, 100)$).

# %%
world = cWorld()
robots = []
for pose in [(40, 40, 0), (60, 50, np.pi / 2), (30, 70, 3 * np.pi / 4)]:
    r = cRobot(rng=np.random.default_rng(SEED))
    r.set(*pose)
    robots.append(r)
plot_world_and_robots(world, robots);


# %% [markdown]
# ## b. The motion model
#
# A command is a rotation $u_{rot}$ followed by a translation $u_{trans}$ along the **new** heading. Both are
# corrupted by zero-mean Gaussian noise (a rotate-translate version of `sample_motion_model_odometry`,
# Table 5.6):
#
# $$
# \begin{aligned}
# \theta' &= \mathrm{wrap}\left(\theta + u_{rot} + \varepsilon_\theta\right), & \varepsilon_\theta &\sim \mathcal N(0, \sigma_{turn}^2)\\
# d &= u_{trans} + \varepsilon_d, & \varepsilon_d &\sim \mathcal N(0, \sigma_{fwd}^2)\\
# x' &= (x + d\cos\theta') \bmod 100, & y' &= (y + d\sin\theta') \bmod 100
# \end{aligned}
# $$
#
# Two remarks on a `move` function often written for this exercise:
#
# * it draws **two** forward-noise samples, one for $x$ and one for $y$. Then the robot no longer moves along its
#   heading (try it: with $\sigma_{turn} = 0$ its displacement still points in a random direction). That is a bug:
#   draw **one** $\varepsilon_d$ per particle.
# * it keeps $\theta$ in $[0, 2\pi)$; robolab uses $[-\pi, \pi)$. Same directions, one convention everywhere.
#
# `cRobot.move` implements this for one robot. Now write it for $N$ particles at once: draw `N` turn-noise samples
# and `N` forward-noise samples from `rng` (e.g. `rng.normal(0.0, turn_noise, size=N)`).

# %% tags=["exercise"]
def move_particles(
    particles, u_rotation, u_translation, forward_noise, turn_noise, rng, world_size=100
):
    """Move every particle with the noisy rotate-then-translate model.

    Section b of this lab, for all particles at once; the rotation/translation
    motion model is Probabilistic Robotics' ``sample_motion_model_odometry``
    (Table 5.6) with no final rotation. For each particle ``i``, independently:

    .. math::

        \\theta_i' &= \\mathrm{wrap}(\\theta_i + u_{rot} + \\varepsilon_{\\theta,i}),
            \\quad \\varepsilon_{\\theta,i} \\sim \\mathcal N(0, \\sigma_{turn}^2) \\\\
        d_i &= u_{trans} + \\varepsilon_{d,i},
            \\quad \\varepsilon_{d,i} \\sim \\mathcal N(0, \\sigma_{fwd}^2) \\\\
        x_i' &= (x_i + d_i \\cos\\theta_i') \\bmod S, \\qquad
        y_i' = (y_i + d_i \\sin\\theta_i') \\bmod S

    One forward-noise sample per particle moves it along its new heading (a
    version that draws one for x and another for y is a bug). Headings are
    wrapped to ``[-pi, pi)``, positions to ``[0, S)`` (the cyclic world).

    Parameters
    ----------
    particles : array_like, shape (N, 3)
        Poses ``(x, y, theta)``; not modified.
    u_rotation : float
        Commanded rotation [rad].
    u_translation : float
        Commanded translation.
    forward_noise : float
        Standard deviation of the translation noise, >= 0.
    turn_noise : float
        Standard deviation of the rotation noise [rad], >= 0.
    rng : numpy.random.Generator
        Source of the noise.
    world_size : float, optional
        Side ``S`` of the cyclic world (default 100).

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        The moved particles, a new array.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_move_particles(move_particles)

# %% [markdown]
# One command applied to 2000 copies of the same pose shows the shape of $p(x_t \mid u_t, x_{t-1})$:
# translation noise stretches the cloud along the heading, rotation noise bends it into a banana.

# %%
start = np.tile([30.0, 30.0, 0.0], (2000, 1))
fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
for ax, (fwd, turn) in zip(axes, [(5.0, 0.02), (1.0, 0.3)]):
    moved = move_particles(start, np.pi / 4, 40.0, fwd, turn, np.random.default_rng(SEED))
    ax.scatter(moved[:, 0], moved[:, 1], s=4, alpha=0.4, label="moved particles")
    ax.plot(30, 30, "ko", label="start (30, 30, 0)")
    ax.set_title(f"u = (pi/4, 40): forward_noise {fwd}, turn_noise {turn}")
    ax.set_xlabel("x [m]"); ax.set_ylabel("y [m]"); ax.set_aspect("equal", adjustable="datalim"); ax.legend()
fig.suptitle("Samples of the motion model");

# %% [markdown]
# ## c. Sensing
#
# `cRobot.sense(world)` returns the range to each landmark plus independent noise $\mathcal N(0, \sigma_{sense}^2)$.
# It uses the **plain Euclidean distance**, without the cyclic wrap: a robot at $x = 95$ is 75 m
# from a landmark at $x = 20$, not 25 m (it sees the landmark "through" the world, not around it).

# %%
forward_noise, turn_noise, sensor_noise = 5.0, 0.5, 5.0
robots[0].set_noise(forward_noise, turn_noise, sensor_noise)
print("true ranges from (40, 40):", np.round(np.hypot(*(np.array([40, 40]) - world.landmarks).T), 2))
print("measured ranges:          ", np.round(robots[0].sense(world), 2))


# %% [markdown]
# ## d. The measurement probability (particle weights)
#
# The four ranges are independent given the pose, so their joint density is the product of four Gaussians
# (the range part of `landmark_model_known_correspondence`, Table 6.4):
#
# $$
# w^{[i]} = p(z \mid x^{[i]}, m) = \prod_{k=1}^{K} \frac{1}{\sqrt{2\pi}\,\sigma}
# \exp\left(-\frac{\left(z_k - \hat r^{[i]}_k\right)^2}{2\sigma^2}\right),
# \qquad \hat r^{[i]}_k = \left\lVert (x^{[i]}, y^{[i]}) - l_k \right\rVert .
# $$
#
# Measure $\hat r$ as `cRobot.sense` does (plain Euclidean, no wrap). Hint: broadcasting an `(N, 1)` against a `(K,)`
# array gives all `(N, K)` differences at once.

# %% tags=["exercise"]
def measurement_probability(measured_ranges, particles, landmarks, sensor_noise):
    """Likelihood of the measured ranges for every particle (section d).

    The ranges to the ``K`` landmarks are independent given the pose, so their
    joint density is the product of Gaussian densities (Probabilistic Robotics,
    Table 6.4, with range only):

    .. math::

        w_i = p(z \\mid x_i, m) = \\prod_{k=1}^{K}
            \\frac{1}{\\sqrt{2\\pi}\\,\\sigma}
            \\exp\\!\\left(-\\frac{(z_k - \\hat r_{i,k})^2}{2\\sigma^2}\\right),
        \\qquad \\hat r_{i,k} = \\lVert (x_i, y_i) - l_k \\rVert

    ``r_hat`` is the plain Euclidean distance, **without** the cyclic wrap,
    exactly as :meth:`robolab.world.cRobot.sense` measures it.
    The heading does not enter.

    Parameters
    ----------
    measured_ranges : array_like, shape (K,)
        One measured range per landmark.
    particles : array_like, shape (N, 3)
        Poses ``(x, y, theta)``.
    landmarks : array_like, shape (K, 2)
        Landmark positions, in the order of ``measured_ranges``.
    sensor_noise : float
        Standard deviation ``sigma`` of each range, > 0.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Unnormalized weights (densities; they may underflow to 0 far from the
        measurement).
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_measurement_probability(measurement_probability)

# %% [markdown]
# Here is the weight every position of the world would get for one measurement taken at $(40, 60)$. One range
# alone puts the robot on a ring around its landmark (left); the product of the four (right, on a **log** scale:
# the density is so peaked that a linear colour scale shows a single dot) is large only where all rings cross.

# %%
xs = np.linspace(0, 100, 201)
gx, gy = np.meshgrid(xs, xs)
grid = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
z_demo = np.hypot(*(np.array([40.0, 60.0]) - world.landmarks).T)
one = measurement_probability(z_demo[:1], grid, world.landmarks[:1], 5.0).reshape(gx.shape)
lik = measurement_probability(z_demo, grid, world.landmarks, 5.0).reshape(gx.shape)
fig, axes = plt.subplots(1, 2, figsize=(12, 5))
images = [(one, "landmark (20, 20) alone: p(z_1 | x) [1/m]"),
          (np.log10(np.maximum(lik, 1e-300)), "all four: log10 p(z | x, m) [log10 m^-4]")]
for ax, (img, label) in zip(axes, images):
    im = ax.imshow(img, origin="lower", extent=(0, 100, 0, 100), cmap="viridis",
                   vmin=None if img is one else img.max() - 30)
    world.plot(ax)
    ax.plot(40, 60, "wx", markersize=10, label="true position (40, 60)")
    ax.legend(loc="upper right", fontsize="small")
    ax.set_title(label.split(":")[0])
    fig.colorbar(im, ax=ax, label=label.split(": ")[1])
fig.suptitle("Measurement likelihood of exact ranges from (40, 60), sigma = 5 m");

# %% [markdown]
# ## e. The intended path
#
# Without noise the commands $u = [0\ 60;\ \pi/3\ 30;\ \pi/4\ 30;\ \pi/4\ 20;\ \pi/4\ 40]$ take the robot from
# $(10, 15, 0)$ along this path.

# %%
U = np.array([[0, 60], [np.pi / 3, 30], [np.pi / 4, 30], [np.pi / 4, 20], [np.pi / 4, 40]])
robot = cRobot(rng=np.random.default_rng(SEED))
robot.set_noise(0.0, 0.0, 5.0)
robot.set(10, 15, 0)
command_path = [[robot.x, robot.y]]
for u_rot, u_trans in U:
    robot.move(u_rot, u_trans)
    command_path.append([robot.x, robot.y])
command_path = np.array(command_path)
plot_paths(world, {"command": (command_path, "k:o")}, title="Intended path (section e)");


# %% [markdown]
# ## f. The true, noisy path and its measurements
#
# Now with $\sigma_{fwd} = 5$, $\sigma_{turn} = 0.1$, $\sigma_{sense} = 5$. After each move the robot measures its
# ranges: `measurements[t]` is the vector of 4 ranges taken after command `U[t]`.

# %%
def simulate(seed, noise=(5.0, 0.1, 5.0)):
    # The true path (T+1, 2) and the measurements (T, 4) of section f.
    robot = cRobot(rng=np.random.default_rng(seed))
    robot.set_noise(*noise)
    robot.set(10, 15, 0)
    path, z = [[robot.x, robot.y]], []
    for u_rot, u_trans in U:
        robot.move(u_rot, u_trans)
        path.append([robot.x, robot.y])
        z.append(robot.sense(world))
    return np.array(path), np.array(z)

true_path, measurements = simulate(SEED)
print("measurements (one row per step, one column per landmark):\n", np.round(measurements, 1))
plot_paths(world, {"command": (command_path, "k:o"), "true position": (true_path, "k-o")},
           title="Command and true path (section f)");


# %% [markdown]
# ## Low-variance resampling (Table 4.4)
#
# After weighting, the filter draws a new, equally weighted particle set in which particle $i$ appears about
# $N w_i$ times. Low-variance (systematic) resampling uses **one** random number: normalize the weights,
# $w_i \leftarrow w_i / \sum_j w_j$, draw $r \sim U[0, 1/N)$ and walk the cumulative sum $c_i = \sum_{j \le i} w_j$
# with $N$ evenly spaced pointers:
#
# $$
# U_m = r + \frac{m}{N}, \quad m = 0, \dots, N - 1, \qquad \text{take particle } i \text{ where } c_{i-1} \le U_m < c_i .
# $$
#
# The contract (the tests rely on it): draw `r = rng.uniform(0.0, 1.0 / N)` **first**, and nothing else from `rng`.
# `np.searchsorted` finds all $i$ in one call. Return **copies** (fancy indexing `particles[idx]` copies; a list
# of row views would let two "different" particles share memory, a classic bug). If the weights are all zero
# (or not finite, or negative) there is no distribution to draw from: raise `ValueError`.

# %% tags=["exercise"]
def low_variance_resample(particles, weights, rng):
    """Low-variance (systematic) resampling, Probabilistic Robotics Table 4.4.

    The weights are normalized first, ``w_i <- w_i / sum_j w_j``. Then **one**
    random offset is drawn, as the very first use of ``rng``:
    ``r = rng.uniform(0.0, 1.0 / N)``, and particle ``i`` is taken once for each
    pointer

    .. math:: U_m = r + \\frac{m}{N}, \\quad m = 0, \\dots, N-1,
              \\qquad c_{i-1} \\le U_m < c_i,\\ \\ c_i = \\sum_{j \\le i} w_j .

    A particle of weight ``w_i`` is therefore taken ``floor(N w_i)`` or
    ``ceil(N w_i)`` times (expected count ``N w_i``), a zero-weight particle
    never, and with equal weights every particle exactly once. The result
    equals ``particles[filterpy.monte_carlo.systematic_resample(w)]`` for the
    same offset (``random() = N r``).

    Parameters
    ----------
    particles : array_like, shape (N, D)
        The particles (rows); not modified.
    weights : array_like, shape (N,)
        Non-negative, finite importance weights; need not sum to 1.
    rng : numpy.random.Generator
        Source of the single offset ``r``.

    Returns
    -------
    numpy.ndarray, shape (N, D)
        A new array of copies: it shares no memory with ``particles`` and its
        rows never alias one another.

    Raises
    ------
    ValueError
        When a weight is negative, NaN or infinite, or when all weights are 0:
        no distribution can be formed from them, and a silent uniform fallback
        would hide a diverged filter. (:func:`particle_filter` decides what to
        do in that case.)
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_low_variance_resample(low_variance_resample)


# %% [markdown]
# ## g. The particle filter (Table 4.3)
#
# All $N$ particles start at the known pose $(10, 15, 0)$. For each command $u_t$ and measurement $z_t$:
#
# 1. **predict** $x_t^{[i]} \sim p(x_t \mid u_t, x_{t-1}^{[i]})$ with `move_particles`;
# 2. **weight** $w_t^{[i]} = p(z_t \mid x_t^{[i]}, m)$ with `measurement_probability`;
# 3. **resample** with `low_variance_resample`;
# 4. **estimate** the position as the mean $(x, y)$ of the resampled particles (they are equally weighted).
#
# If all weights of a step are 0, keep the predicted particles (resample with uniform weights). `world` may be a
# `cWorld` or a plain `(K, 2)` landmark array; `noise` is a dict with keys `forward_noise`, `turn_noise`,
# `sensor_noise` (or those three numbers). With `return_history=True` return a dict with `"path"`,
# `"predicted"`, `"weights"` and `"resampled"` (shapes in the docstring).

# %% tags=["exercise"]
def particle_filter(
    world,
    controls,
    measurements,
    n_particles,
    noise,
    rng,
    initial_pose=(10.0, 15.0, 0.0),
    world_size=100,
    return_history=False,
):
    """The particle filter of section g (Probabilistic Robotics Table 4.3).

    All particles start at the known ``initial_pose``. For every step ``t``:

    1. predict: ``x_t^[i] ~ p(x_t | u_t, x_{t-1}^[i])`` with :func:`move_particles`;
    2. weight: ``w_t^[i] = p(z_t | x_t^[i], m)`` with :func:`measurement_probability`;
    3. resample with :func:`low_variance_resample` (Table 4.4);
    4. estimate the position as the mean of the resampled, equally weighted
       particles, ``(mean x, mean y)`` (the plain mean ignores the
       cyclic wrap, fine while the cloud stays away from the edges).

    If every weight of a step is 0 (the measurement is impossible for all
    particles: the filter has lost the robot, e.g. with a far too small
    ``sensor_noise``), the step keeps the predicted particles unchanged
    (uniform weights) instead of failing.

    Parameters
    ----------
    world : cWorld or array_like, shape (K, 2)
        The landmarks, as a :class:`robolab.world.cWorld` or a plain array.
    controls : array_like, shape (T, 2)
        One ``(u_rotation, u_translation)`` per step.
    measurements : array_like, shape (T, K)
        The ranges measured after each move.
    n_particles : int
        Number of particles ``N`` >= 1.
    noise : dict or sequence
        The model's noise: ``{"forward_noise": .., "turn_noise": .., "sensor_noise": ..}``
        or the three values in that order.
    rng : numpy.random.Generator
        Source of every random number.
    initial_pose : sequence of 3 floats, optional
        The known start ``(x, y, theta)``, default ``(10, 15, 0)``.
    world_size : float, optional
        Side of the cyclic world (default 100; a cWorld's own size wins).
    return_history : bool, optional
        Also return the particles of every step.

    Returns
    -------
    path : numpy.ndarray, shape (T + 1, 2)
        The estimated positions, starting with ``initial_pose[:2]``.
        With ``return_history=True``, a dict instead, with ``"path"`` as above,
        ``"predicted"`` (T, N, 3) the particles after each prediction,
        ``"weights"`` (T, N) their weights and ``"resampled"`` (T, N, 3) the
        particles after each resampling.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_particle_filter(particle_filter)

# %%
NOISE = {"forward_noise": 5.0, "turn_noise": 0.1, "sensor_noise": 5.0}
history = particle_filter(world, U, measurements, 1000, NOISE, np.random.default_rng(SEED), return_history=True)
plot_filter_run(world, history, command_path, true_path, measurements=measurements,
                title="Particle filter, N = 1000 (section g)")
errors = np.linalg.norm(history["path"] - true_path, axis=1)
command_errors = np.linalg.norm(command_path - true_path, axis=1)
print("position error per step [m]:", np.round(errors, 2))
print("command path error per step [m]:", np.round(command_errors, 2))
worst = int(np.argmax(errors))
print(f"worst estimate: step {worst + 1} ({errors[worst]:.2f} m); "
      f"mean error of the filter {errors.mean():.2f} m against {command_errors.mean():.2f} m "
      "for the command path")

# %% [markdown]
# **Question.** Which step has the worst estimate (printed above)? Look at the projected particles of that
# step and at where the landmark rings cross: why is it worse there? And why are the filter's estimates after
# a few steps much better than the command path?
#
# *Your answer here.*

# %% [markdown]
# ## How many particles?
#
# The filter is a Monte Carlo approximation: more particles, better approximation, more time. Run it for several
# $N$ and several random seeds on the same true path.

# %%
ns = np.array([10, 30, 100, 300, 1000, 3000])
seeds = range(8)
final_err = np.array([[np.linalg.norm(particle_filter(world, U, measurements, n, NOISE,
                                                      np.random.default_rng(s))[-1] - true_path[-1])
                       for s in seeds] for n in ns])
plot_error_vs_particles(ns, final_err, title="Final position error against N (8 runs per N)");

# %% [markdown]
# **Question.** Why does the error stop decreasing beyond a few hundred particles? (Hint: what does the filter
# estimate — the true position, or something else?)
#
# *Your answer here.*

# %% [markdown]
# ### Watch it, then try it
#
# The replay below steps through the run of section g: the predicted particles (orange), the resampled ones
# (red), and the estimate against the true path. The sliders after it rerun *your* `particle_filter` with
# other noise levels and particle counts (without Jupyter widgets: one figure at the defaults). Try a
# sensor noise of 1 m with 100 particles, then 10 000 particles.

# %%
from robolab.plotting.animation import animate_landmark_pf, show_animation

show_animation(animate_landmark_pf(world, history, true_path))

# %%
from robolab.plotting.interactive import landmark_pf_explorer

landmark_pf_explorer(particle_filter, world, U, measurements, true_path, seed=SEED);

# %% [markdown]
# ## Low-variance against multinomial resampling
#
# Multinomial resampling draws $N$ independent indices with probabilities $w_i$
# (`rng.choice(N, N, p=w)`): particle $i$'s copy count is Binomial$(N, w_i)$, variance $N w_i (1 - w_i)$.
# Low-variance resampling takes particle $i$ either $\lfloor N w_i \rfloor$ or $\lceil N w_i \rceil$ times: the
# variance is $p(1-p) \le 1/4$ with $p$ the fractional part of $N w_i$. Less resampling noise means the filter
# loses less diversity by chance. Measure both on real filter weights (step 2 of the run above).

# %%
pick = np.random.default_rng(SEED).choice(1000, 100, replace=False)   # 100 particles of step 2 and
w = history["weights"][1][pick]                                        # their weights, renormalized
w = w / w.sum()
n = len(w)
ids = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])
rng = np.random.default_rng(SEED)
counts_lv = np.array([np.bincount(low_variance_resample(ids, w, rng)[:, 0].astype(int), minlength=n)
                      for _ in range(2000)])
counts_mn = np.array([np.bincount(rng.choice(n, n, p=w), minlength=n) for _ in range(2000)])
plot_count_variance(n * w, counts_lv.var(axis=0), counts_mn.var(axis=0),
                    title="Copy-count variance over 2000 resamplings (N = 100)")
print(f"mean count variance: low-variance {counts_lv.var(axis=0).mean():.3f}, "
      f"multinomial {counts_mn.var(axis=0).mean():.3f}")

# %% [markdown]
# **Question.** With all weights equal, how many copies of each particle does each resampler produce? Why does
# that matter when the robot is not moving and the measurements carry no new information?
#
# *Your answer here.*

# %% [markdown]
# ## Too little sensor noise in the model: particle deprivation
#
# The real sensor has $\sigma = 5$ m. What if the filter *believes* the sensor is ten times better,
# $\sigma_{model} = 0.5$ m? Then a particle 2 m off gets a weight $e^{-8}$ times smaller per landmark: after each
# resampling only a handful of particles survive and the cloud collapses — **particle deprivation**. Run both models
# on 40 simulated true paths and count the distinct particles left after each resampling.

# %%
settings = {"model sigma = 5 m (true)": 5.0, "model sigma = 0.5 m": 0.5}
dep_errors, dep_distinct = [], []
for sigma in settings.values():
    errs, distinct = [], []
    for k in range(40):
        truth_k, z_k = simulate(1000 + k)
        h = particle_filter(world, U, z_k, 1000, {**NOISE, "sensor_noise": sigma},
                            np.random.default_rng(k), return_history=True)
        errs.append(np.linalg.norm(h["path"][1:] - truth_k[1:], axis=1).mean())
        distinct.append([len(np.unique(h["resampled"][t], axis=0)) for t in range(len(U))])
    dep_errors.append(errs)
    dep_distinct.append(np.mean(distinct, axis=0))
plot_deprivation(dep_errors, dep_distinct, list(settings),
                 title="Particle deprivation: N = 1000, 40 true paths")
for label, e, d in zip(settings, dep_errors, dep_distinct):
    print(f"{label}: median error {np.median(e):.2f} m, worst {np.max(e):.2f} m, "
          f"distinct particles per step {np.round(d).astype(int)}")

# %% [markdown]
# **Question.** The overconfident filter keeps only a few distinct particles per step. Why is its error not
# dramatically worse on this short, 5-step path — and what would happen on a long run, or when the robot is
# kidnapped? Name two remedies (think of the measurement model and of the resampling step).
#
# *Your answer here.*

# %% [markdown]
# **Question.** The measurement model uses the plain Euclidean distance on a cyclic world. Where in the world
# does that disagree with the shortest distance, and what would the robot have to measure for the cyclic distance to be
# the right model?
#
# *Your answer here.*
