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
#     lab: mcl
# ---

# %% [markdown]
# # Lab 05 — Monte Carlo localization on a bag
#
# A robot wakes up somewhere in an office building. It has a map (`data/office.yaml`), wheel odometry that
# drifts, and a 360-beam laser scanner. **Monte Carlo localization** (MCL, Probabilistic Robotics Table 8.2)
# represents its belief by particles, moves them with the **odometry motion model** (Table 5.6), weighs them
# with the **likelihood field** of the laser (Table 6.3) and **resamples** (Table 4.4). You will build it step
# by step, run it over the bundled bag `data/localization.bag` against its ground
# truth — once from a uniform start (**global localization**) and once from a Gaussian around the known
# start (**tracking**) — and then add two things the ROS `amcl` package does beyond the basic algorithm:
# **KLD-sampling** (adaptive particle counts, Table 8.4) and **recovery** from a kidnapping (augmented MCL,
# Table 8.3).
#
# Everything works on **all particles at once**: a particle set is an `(N, 3)` array of poses
# $(x, y, \theta)$ in metres and radians, weights are `(N,)`. Randomness comes only from the `rng`
# argument (a `numpy.random.Generator`). Angles are wrapped to $[-\pi, \pi)$ with
# `robolab.geometry.wrap_angle`.

# %%
import numpy as np
import matplotlib.pyplot as plt

from robolab.geometry import angle_diff, compose, wrap_angle
from robolab.maps import OccupancyGrid
from robolab.validation import as_array, as_poses, check_positive
from robolab.plotting import plot_map, plot_particles, plot_poses
from robolab.plotting import mcl as mclplot
from robolab.checks import mcl as checks

SEED = 5  # one random seed for the whole notebook: rerunning gives the same figures

# %% [markdown]
# ## The data
#
# `mclplot.load_localization()` reads the bag with `robolab.bag.BagReader` (lab 00) and returns arrays at
# the **scan stamps**: the scans, the odometry `odom -> base_link` interpolated at each scan, the ground
# truth `map -> base_link` (which the filter never sees: it is only for judging it) and the laser's mount
# `base_link -> base_laser_link` from `/tf`. The robot starts inside one of **four identical offices**
# north of the corridor, so at first the laser cannot tell which office it is in.

# %%
data = mclplot.load_localization()
grid = data.grid
print(f"{len(data)} scans over {data.t[-1]:.1f} s, {data.ranges.shape[1]} beams, range_max {data.range_max} m")
print("laser pose in base_link:", data.laser_pose)

ax = plot_map(grid, title="Office map and the ground-truth path of the localization bag")
plot_poses(data.truth, ax, color="tab:green", label="ground truth", arrow_every=40)
raw = compose(data.truth[0], data.odom)  # odometry placed at the true start
plot_poses(raw, ax, color="tab:orange", label="raw odometry", arrows=False, linestyle="--")
ax.legend(loc="lower right");


# %% [markdown]
# ## 3.1 Initialize the particle distribution
#
# **Global localization** knows nothing: the prior is uniform over the free space and over the heading,
#
# $$ (x, y) \sim \mathcal U(\text{free cells}), \qquad \theta \sim \mathcal U[-\pi, \pi). $$
#
# Draw a free cell uniformly (`np.nonzero(grid.free)`), then a point uniformly **inside** the cell (not at
# its centre: `grid.cell_to_world` maps a fractional `(row, col)` to metres, the centre being at integer
# indices), and a heading.
#
# **Tracking** knows the start approximately: $x_0 \sim \mathcal N(\mu, \Sigma)$ (ROS `amcl`'s
# `initial_pose` with `initial_cov_xx`, `initial_cov_yy`, `initial_cov_aa`). Wrap the heading afterwards.

# %% tags=["exercise"]
def init_uniform(grid, n, rng):
    r"""Particles drawn uniformly over the free space of a map (global localization).

    A cell is drawn uniformly among the map's free cells, then a position
    uniformly *inside* that cell (not at its centre), and a heading uniformly in
    :math:`[-\pi, \pi)`:

    .. math::

        (x, y) \sim \mathcal{U}(\text{free space}), \qquad
        \theta \sim \mathcal{U}[-\pi, \pi).

    This is the prior :math:`bel(x_0)` of global localization (Probabilistic
    Robotics, section 8.3; AMCL's ``pf_init_model`` with the free-space sampler).

    Parameters
    ----------
    grid : robolab.maps.OccupancyGrid
        The map; only its known free cells (``grid.free``) receive particles.
    n : int
        Number of particles, >= 1.
    rng : numpy.random.Generator
        The only source of randomness.

    Returns
    -------
    numpy.ndarray, shape (n, 3)
        Poses ``(x, y, theta)`` in the map frame, metres and radians.

    Raises
    ------
    TypeError
        If ``grid`` is not an OccupancyGrid, ``n`` not an integer or ``rng`` not a Generator.
    ValueError
        If ``n < 1`` or the map has no free cell.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_init_uniform(init_uniform)


# %% tags=["exercise"]
def init_gaussian(pose, cov, n, rng):
    r"""Particles drawn from a Gaussian around a known pose (position tracking).

    .. math::

        x_0^{[m]} \sim \mathcal{N}(\mu, \Sigma), \quad m = 1 \dots n,

    with the heading wrapped to :math:`[-\pi, \pi)` afterwards (AMCL's
    ``initial_pose`` with ``initial_cov_xx``, ``initial_cov_yy``, ``initial_cov_aa``).

    Parameters
    ----------
    pose : array_like, shape (3,)
        Mean ``(x, y, theta)``, metres and radians.
    cov : array_like, shape (3, 3)
        Covariance, symmetric positive semi-definite (m^2, rad^2); zero gives
        ``n`` copies of ``pose``.
    n : int
        Number of particles, >= 1.
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (n, 3)

    Raises
    ------
    ValueError
        Bad shapes, a non-finite value, a covariance that is not symmetric or
        has a negative eigenvalue, or ``n < 1``.
    TypeError
        ``n`` not an integer or ``rng`` not a Generator.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_init_gaussian(init_gaussian)

# %%
rng = np.random.default_rng(SEED)
ax = plot_map(grid, title="Initial particles: uniform (global) and Gaussian (tracking)")
plot_particles(init_uniform(grid, 3000, rng), ax=ax, size=4, label="uniform, 3000")
plot_particles(init_gaussian(data.truth[0], np.diag([0.1**2, 0.1**2, 0.1**2]), 300, rng), ax=ax,
               color="tab:blue", size=5, label="Gaussian, 300")
ax.legend(loc="lower right");


# %% [markdown]
# ## 3.2 The motion model
#
# Between two filter updates the odometry moved from $\bar x_{t-1} = (\bar x, \bar y, \bar\theta)$ to
# $\bar x_t = (\bar x', \bar y', \bar\theta')$ (Probabilistic Robotics, Table 5.6). The motion is decomposed into a rotation, a
# translation and a second rotation (Table 5.6, lines 2-4):
#
# $$
# \delta_{trans} = \sqrt{(\bar x' - \bar x)^2 + (\bar y' - \bar y)^2}, \qquad
# \delta_{rot1} = \operatorname{atan2}(\bar y' - \bar y,\ \bar x' - \bar x) - \bar\theta, \qquad
# \delta_{rot2} = \bar\theta' - \bar\theta - \delta_{rot1}.
# $$
#
# Each particle gets its own noisy version (Probabilistic Robotics **Table 5.6**), where
# $\varepsilon(b^2)$ is a zero-mean Gaussian with **variance** $b^2$:
#
# $$
# \hat\delta_{rot1} = \delta_{rot1} - \varepsilon(\alpha_1 \delta_{rot1}^2 + \alpha_2 \delta_{trans}^2), \quad
# \hat\delta_{trans} = \delta_{trans} - \varepsilon(\alpha_3 \delta_{trans}^2 + \alpha_4 \delta_{rot1}^2 + \alpha_4 \delta_{rot2}^2), \quad
# \hat\delta_{rot2} = \delta_{rot2} - \varepsilon(\alpha_1 \delta_{rot2}^2 + \alpha_2 \delta_{trans}^2)
# $$
#
# and moves (Table 5.6, lines 8-10): $x' = x + \hat\delta_{trans}\cos(\theta + \hat\delta_{rot1})$,
# $y' = y + \hat\delta_{trans}\sin(\theta + \hat\delta_{rot1})$,
# $\theta' = \theta + \hat\delta_{rot1} + \hat\delta_{rot2}$.
#
# > **Careful with a common rewriting of Table 5.6.** Some write-ups of this model give the noise as
# > $\varepsilon_{\alpha_1|\delta_{rot2}| + \alpha_2|\delta_{trans}|}$: a *standard deviation* linear in the
# > motion (that is what AMCL's old `diff` model does), and with $\delta_{rot2}$ in the noise of
# > $\delta_{rot1}$. Table 5.6 uses **variances** $\alpha_1\delta_{rot1}^2 + \alpha_2\delta_{trans}^2$, so that
# > $\alpha$ are dimensionless ratios. Implement Table 5.6.
#
# Two details from AMCL (`amcl_odom.cpp`):
#
# * **in-place rotation**: when $\delta_{trans} < 0.01$ m the bearing `atan2` of two almost equal positions is
#   noise, so $\delta_{rot1} = 0$;
# * **`corrected=True`** is AMCL's `diff-corrected` model: driving backwards gives
#   $\delta_{rot1} \approx \pm\pi$, and Table 5.6 would add huge rotation noise. AMCL uses
#   $\min(|\delta_{rot}|, |\pi - |\delta_{rot}||)$ in the noise terms instead (the means stay the same).
#
# Draw all the noise at once (one `rng.standard_normal((N, 3))`), no loop over particles.

# %% tags=["exercise"]
def sample_motion_model_odometry(particles, odom_prev, odom_now, alphas, rng, corrected=False):
    r"""Move every particle by the odometry, with noise: Probabilistic Robotics, Table 5.6.

    The odometry motion from :math:`\bar x = (\bar x, \bar y, \bar\theta)`
    (``odom_prev``) to :math:`\bar x' ` (``odom_now``) is decomposed as

    .. math::

        \delta_{trans} = \sqrt{(\bar x' - \bar x)^2 + (\bar y' - \bar y)^2}, \quad
        \delta_{rot1} = \operatorname{atan2}(\bar y' - \bar y, \bar x' - \bar x) - \bar\theta, \quad
        \delta_{rot2} = \bar\theta' - \bar\theta - \delta_{rot1}

    (Table 5.6, lines 2-4). AMCL's guard: when :math:`\delta_{trans} < 0.01` m
    the bearing of two nearly equal positions is noise, so
    :math:`\delta_{rot1} = 0` (an in-place rotation). Each particle gets its own
    noisy motion,

    .. math::

        \hat\delta_{rot1} &= \delta_{rot1} - \varepsilon(\alpha_1 \delta_{rot1}^2 + \alpha_2 \delta_{trans}^2) \\
        \hat\delta_{trans} &= \delta_{trans} - \varepsilon(\alpha_3 \delta_{trans}^2
                               + \alpha_4 \delta_{rot1}^2 + \alpha_4 \delta_{rot2}^2) \\
        \hat\delta_{rot2} &= \delta_{rot2} - \varepsilon(\alpha_1 \delta_{rot2}^2 + \alpha_2 \delta_{trans}^2)

    where :math:`\varepsilon(b^2)` is a zero-mean Gaussian of **variance**
    :math:`b^2`. (Some write-ups of this model give the noise as
    :math:`\varepsilon_{\alpha_1|\delta_{rot2}| + \alpha_2|\delta_{trans}|}`: without
    the squares, i.e. as a standard deviation -- which is what AMCL's plain
    ``ODOM_MODEL_DIFF`` does -- and with :math:`\delta_{rot2}` in the noise of
    :math:`\delta_{rot1}`; Table 5.6 uses variances and :math:`\delta_{rot1}`.)
    Then (Table 5.6, lines 8-10)

    .. math::

        x' = x + \hat\delta_{trans}\cos(\theta + \hat\delta_{rot1}), \quad
        y' = y + \hat\delta_{trans}\sin(\theta + \hat\delta_{rot1}), \quad
        \theta' = \theta + \hat\delta_{rot1} + \hat\delta_{rot2}.

    With ``corrected=True`` this is AMCL's ``ODOM_MODEL_DIFF_CORRECTED``
    (``amcl_odom.cpp``): backward motion (:math:`\delta_{rot1} \approx \pm\pi`)
    is treated like forward motion in the noise, which uses
    :math:`\min(|\delta_{rot}|, |\pi - |\delta_{rot}||)` in place of
    :math:`|\delta_{rot}|` for both rotations (the means are unchanged).

    Parameters
    ----------
    particles : array_like, shape (N, 3)
        Poses before the motion; not modified.
    odom_prev, odom_now : array_like, shape (3,)
        Odometry poses ``(x, y, theta)`` in the odom frame at the previous and
        the current step.
    alphas : array_like, shape (4,)
        :math:`\alpha_1 \dots \alpha_4` (rad^2/rad^2, rad^2/m^2, m^2/m^2, m^2/rad^2), >= 0.
    rng : numpy.random.Generator
        Draws one ``(N, 3)`` block of standard normals.
    corrected : bool
        Use AMCL's diff-corrected noise.

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        New poses, heading wrapped to :math:`[-\pi, \pi)`.

    Raises
    ------
    ValueError
        Bad shapes, non-finite values or a negative alpha.
    TypeError
        ``rng`` is not a Generator or ``corrected`` not a bool.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_sample_motion_model_odometry(sample_motion_model_odometry)

# %%
rng = np.random.default_rng(SEED)
alphas = (0.05, 0.05, 0.05, 0.05)
fig, axes = plt.subplots(1, 2, figsize=(11, 4))
cloud = np.zeros((1, 3))
path = [np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([2.0, 0.0, np.pi / 2]), np.array([2.0, 1.0, np.pi / 2])]
clouds = np.zeros((2000, 3))
for a, b in zip(path[:-1], path[1:]):
    clouds = sample_motion_model_odometry(clouds, a, b, alphas, rng)
    axes[0].scatter(clouds[:, 0], clouds[:, 1], s=4, alpha=0.4, label=f"after odometry reaches {b[:2]}")
axes[0].set(title="Table 5.6: 2000 particles after three odometry steps", xlabel="x [m]", ylabel="y [m]", aspect="equal")
axes[0].legend(fontsize=7, markerscale=5)
for corrected, color in ((False, "tab:red"), (True, "tab:blue")):
    back = sample_motion_model_odometry(np.zeros((2000, 3)), [0, 0, 0], [-0.5, 0, 0], alphas,
                                        np.random.default_rng(SEED), corrected=corrected)
    axes[1].scatter(back[:, 0], back[:, 1], s=4, alpha=0.4, color=color,
                    label=f"corrected={corrected}")
axes[1].set(title="Backing up 0.5 m: plain vs AMCL diff-corrected", xlabel="x [m]", ylabel="y [m]", aspect="equal")
axes[1].legend(markerscale=5)
fig.tight_layout()


# %% [markdown]
# ## 3.3 The measurement model: a likelihood field
#
# The **likelihood field** (Probabilistic Robotics section 6.4) pre-computes, for every cell, the distance
# $d$ to the nearest obstacle: the Euclidean distance transform of the occupancy mask
# (`scipy.ndimage.distance_transform_edt(~grid.occupied)`, in cells) times the **resolution** (the map is in
# cells, the laser in metres), clipped at $d_{max}$ (AMCL's
# `laser_likelihood_max_dist`). A beam endpoint at distance $d$ from an obstacle has the hit likelihood
# $\mathcal N(d; 0, \sigma_{hit}^2) = \frac{1}{\sqrt{2\pi}\sigma_{hit}} e^{-d^2/2\sigma_{hit}^2}$.
#
# Return plain data: a dict with `"distance"` (H, W) in metres, `"likelihood"` (H, W), `"resolution"`,
# `"origin"` (the grid's), `"sigma_hit"` and `"max_dist"`.

# %% tags=["exercise"]
def likelihood_field(grid, sigma_hit, max_dist):
    r"""The likelihood field of a map: distance to the nearest obstacle, precomputed per cell.

    For every cell centre :math:`c`, the Euclidean distance to the nearest
    occupied cell centre, in metres (the distance transform of the occupancy
    mask times the resolution), clipped at ``max_dist`` (AMCL's
    ``laser_likelihood_max_dist``):

    .. math::

        d(c) = \min\big(\min_{o \in \text{occupied}} \lVert c - o \rVert,\ d_{max}\big),
        \qquad
        p_{hit}(c) = \mathcal N(d(c); 0, \sigma_{hit}^2)
                   = \frac{1}{\sqrt{2\pi}\sigma_{hit}} e^{-d(c)^2 / 2\sigma_{hit}^2}

    (Probabilistic Robotics, section 6.4 and Table 6.3, ``prob(dist, sigma_hit)``).
    Unknown cells are not obstacles. A map without any obstacle has
    :math:`d = d_{max}` everywhere.

    Parameters
    ----------
    grid : robolab.maps.OccupancyGrid
    sigma_hit : float
        Standard deviation of the hit noise, metres, > 0.
    max_dist : float
        Clipping distance, metres, > 0.

    Returns
    -------
    dict
        ``"distance"``: (H, W) metres, indexed ``[row, col]`` like ``grid.data``;
        ``"likelihood"``: (H, W) :math:`p_{hit}` in 1/m;
        ``"resolution"``: float (m/cell); ``"origin"``: (3,) the grid's origin;
        ``"sigma_hit"``, ``"max_dist"``: floats. Plain data only.

    Raises
    ------
    TypeError
        ``grid`` is not an OccupancyGrid.
    ValueError
        ``sigma_hit <= 0`` (or so small that the Gaussian's peak overflows) or
        ``max_dist <= 0``.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_likelihood_field(likelihood_field)

# %%
SIGMA_HIT, MAX_DIST = 0.1, 2.0
field = likelihood_field(grid, SIGMA_HIT, MAX_DIST)
mclplot.plot_likelihood_field(field, title="Likelihood field in log space");


# %% [markdown]
# **Table 6.3** scores a scan for a pose $x$. Each valid beam $k$ (range $z^k$, angle $\theta_k$ in the laser
# frame) is projected from the **laser's** pose $x \oplus x_{laser}$ (the laser is mounted 10 cm ahead of
# `base_link`: `compose(particles, params["laser_pose"])`):
#
# $$
# x_{z^k} = x_{l} + z^k\cos(\theta_{l} + \theta_k), \quad y_{z^k} = y_{l} + z^k\sin(\theta_{l} + \theta_k),
# $$
#
# looked up in the field (world to cell with `OccupancyGrid.world_to_cell`-style arithmetic: the field's
# `origin` and `resolution`), and the per-beam mixture is multiplied — in log space, summed:
#
# $$
# \log p(z \mid x, m) = \sum_k \log\Big(z_{hit}\,\mathcal N(d(x_{z^k}); 0, \sigma_{hit}^2) + \frac{z_{rand}}{z_{max}}\Big).
# $$
#
# * Beams that are not real returns are **skipped**: NaN, `inf` (nothing in range), below `range_min`, and
#   **max-range** readings (`>= range_max`: a failed return says nothing about where the robot is).
# * An endpoint **outside the map** is scored as if it were at $d_{max}$: the smallest
#   per-beam likelihood, a penalty that keeps the particle alive but behind those whose beams land in the map.
# * `params["max_beams"]` keeps every $\lfloor (B-1)/(\text{max\_beams}-1) \rfloor$-th beam, like AMCL.
#
# Vectorize over particles **and** beams: the endpoints are an `(N, K)` array; no Python loop.
#
# Finally, weights from log-weights without underflow: with 60 beams $\log p$ is around $-100$ and
# $e^{-100}$ is fine, but $e^{-1000}$ is 0 in float64. Subtract the maximum first:
# $w_i = e^{\ell_i - \max_j \ell_j} / \sum_k e^{\ell_k - \max_j \ell_j}$.

# %% tags=["exercise"]
def likelihood_field_model(scan, particles, field, params):
    r"""Log-likelihood :math:`\log p(z \mid x, m)` of a scan for every particle: Table 6.3.

    Each valid beam :math:`k` (range :math:`z^k`, angle :math:`\theta_k` in the
    laser frame) is projected from the laser's pose
    :math:`x_{laser} = x \oplus x_{laser}^{base}` (``params["laser_pose"]``):

    .. math::

        x_{z^k} = x_{laser} + z^k \cos(\theta_{laser} + \theta_k), \quad
        y_{z^k} = y_{laser} + z^k \sin(\theta_{laser} + \theta_k),

    looked up in the field (world -> cell with the map's resolution and origin,
    see above), and scored with the mixture

    .. math::

        \log p(z \mid x, m) = \sum_k \log\Big( z_{hit}\, \mathcal N(d(x_{z^k}); 0, \sigma_{hit}^2)
                                             + \frac{z_{rand}}{z_{max}} \Big)

    with :math:`z_{max}` the scan's ``range_max``. Beams that are not real
    returns (NaN, inf, outside ``[range_min, range_max)``: max-range readings
    carry no position information, AMCL skips them) are skipped. An endpoint
    outside the map is scored as if at :math:`d_{max}` (as above,
    AMCL's ``max_occ_dist``): the smallest per-beam likelihood, a penalty that
    stays finite. ``params["max_beams"]`` keeps every ``(B - 1) // (max_beams - 1)``-th
    beam as AMCL does. The mixture is summed in log space, so the result is
    finite even for ``z_rand = 0``.

    Parameters
    ----------
    scan : dict
        ``"ranges"`` (B,), ``"angles"`` (B,) radians, ``"range_min"``, ``"range_max"`` metres.
    particles : array_like, shape (N, 3)
    field : dict
        From :func:`likelihood_field` (uses ``distance``, ``resolution``,
        ``origin``, ``sigma_hit``, ``max_dist``).
    params : dict
        ``z_hit``, ``z_rand`` (>= 0, not both 0), optional ``laser_pose`` (3,)
        and ``max_beams``; see :data:`DEFAULT_PARAMS`.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Log-likelihoods (natural log); 0 for every particle if no beam is valid.
        Use :func:`normalize_log_weights` to turn them into weights.

    Raises
    ------
    TypeError
        ``params`` is not a dict.
    ValueError
        A negative mixture weight ``params["z_hit"]`` or ``params["z_rand"]``, both
        0, an unknown key in ``params``; ``particles`` not (N, 3); a scan whose
        ranges and angles differ in length.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_likelihood_field_model(likelihood_field_model)


# %% tags=["exercise"]
def normalize_log_weights(logw):
    r"""Normalized weights from log-weights, without underflow.

    .. math::

        w_i = \frac{e^{\ell_i - \max_j \ell_j}}{\sum_k e^{\ell_k - \max_j \ell_j}}

    Subtracting the maximum changes nothing mathematically but keeps the
    largest term at :math:`e^0 = 1`, so a scan of 60 beams whose
    log-likelihoods are around -300 does not become 0 / 0.

    Parameters
    ----------
    logw : array_like, shape (N,)
        Log-weights; ``-inf`` (weight 0) allowed, NaN and ``+inf`` not.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Non-negative, sums to 1.

    Raises
    ------
    ValueError
        NaN or ``+inf`` entries, an empty array, or every entry ``-inf``.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_normalize_log_weights(normalize_log_weights)

# %%
# the log-likelihood of the first scan for particles at the true heading on a grid of positions
xs, ys = np.meshgrid(np.arange(0.0, 20.0, 0.1), np.arange(0.0, 12.0, 0.1))
poses = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, data.truth[0, 2])])
params_demo = {"z_hit": 0.9, "z_rand": 0.1, "laser_pose": data.laser_pose, "max_beams": 60}
logw = likelihood_field_model(data.scan(0), poses, field, params_demo)
ax = plot_map(grid, title="log p(z_0 | x, m) of the first scan at the true heading")
im = ax.imshow(np.maximum(logw.reshape(xs.shape), logw.max() - 150), origin="lower", extent=(0, 20, 0, 12),
               alpha=0.75, cmap="magma")
plt.colorbar(im, ax=ax, label="log-likelihood [nats], clipped 150 below the best", shrink=0.8)
ax.plot(*data.truth[0, :2], "c*", ms=12, label="true pose")
ax.legend(loc="lower right");


# %% [markdown]
# Four bright spots: the four identical offices explain the first scan equally well. That is why global
# localization must wait until the robot has seen something that breaks the symmetry.
#
# ## 3.4 Resampling
#
# Paste your **lab 03** `low_variance_resample(particles, weights, rng)` (Table 4.4): one random offset
# $r \sim \mathcal U[0, 1/N)$, pointers $r + m/N$, `np.searchsorted` on the cumulative weights.

# %% tags=["exercise"]
def low_variance_resample(particles, weights, rng):
    r"""Low-variance (systematic) resampling, Probabilistic Robotics Table 4.4 -- from lab 03.

    One offset :math:`r \sim \mathcal U[0, 1/N)`, pointers
    :math:`U_m = r + m/N`, and particle :math:`i` is taken for each pointer with
    :math:`c_{i-1} \le U_m < c_i` (:math:`c_i` the cumulative normalized weights).

    Parameters
    ----------
    particles : array_like, shape (N, D)
    weights : array_like, shape (N,)
        Non-negative, finite, not all zero; need not sum to 1.
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (N, D)
        A new array of copies of the selected rows.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_low_variance_resample(low_variance_resample)

# %% [markdown]
# ## The MCL step (Table 8.2) with AMCL's update rules
#
# One step: move every particle with the odometry since the last update (3.2), multiply its weight by the
# likelihood of the scan (3.3), normalize, and resample (3.4) to uniform weights. Return
# `(particles, weights, updated)`.
#
# AMCL does not update on every scan (its `update_min_d` and `update_min_a` parameters; here in `params`):
#
# * `update_min_d`, `update_min_a`: update only when the robot moved at least that far or turned at least that
#   much since `odom_prev` (the odometry of the last update); otherwise return the inputs unchanged with
#   `updated=False`. Resampling a filter that did not move only loses diversity. `force_update=True`
#   updates anyway (the first scan).
# * `resample_interval`: resample only on every `resample_interval`-th update (`update_count` updates were
#   done before this one); in between, the weights carry over.
#
# `params` may omit keys; `DEFAULT_PARAMS` below lists them all with AMCL-like defaults.

# %%
DEFAULT_PARAMS = {
    "alphas": (0.05, 0.05, 0.05, 0.05), "corrected": False,
    "z_hit": 0.95, "z_rand": 0.05, "laser_pose": (0.0, 0.0, 0.0), "max_beams": None,
    "update_min_d": 0.0, "update_min_a": 0.0, "resample_interval": 1, "update_count": 0, "force_update": False,
    "alpha_slow": 0.001, "alpha_fast": 0.1,
}


# %% tags=["exercise"]
def mcl_step(particles, weights, odom_prev, odom_now, scan, field, params, rng):
    r"""One step of Monte Carlo localization: predict, weight, resample (Table 8.2, AMCL).

    .. math::

        x_t^{[m]} \sim p(x_t \mid u_t, x_{t-1}^{[m]}) \ \text{(Table 5.6)}, \qquad
        w_t^{[m]} \propto w_{t-1}^{[m]}\, p(z_t \mid x_t^{[m]}, m) \ \text{(Table 6.3)},

    then low-variance resampling (Table 4.4) and uniform weights :math:`1/N`.

    AMCL's options, all in ``params``:

    * ``update_min_d``, ``update_min_a``: the filter updates only once the
      robot has moved at least ``update_min_d`` metres or turned
      ``update_min_a`` radians since ``odom_prev``; otherwise nothing changes
      and the function returns ``updated = False`` -- the caller then keeps
      ``odom_prev`` (the odometry of the last update) for the next call, so
      small motions accumulate. ``force_update=True`` updates regardless
      (AMCL does so on the first scan).
    * ``resample_interval``: resample only on every ``resample_interval``-th
      update; ``update_count`` is the number of updates done before this one,
      so this update resamples when ``(update_count + 1) % resample_interval == 0``.
      Between resamplings the weights carry over, multiplied by the likelihoods.
    * ``alphas``, ``corrected`` for :func:`sample_motion_model_odometry`;
      ``z_hit``, ``z_rand``, ``laser_pose``, ``max_beams`` for
      :func:`likelihood_field_model`.

    Parameters
    ----------
    particles : array_like, shape (N, 3)
    weights : array_like, shape (N,)
        Non-negative; normalized inside.
    odom_prev, odom_now : array_like, shape (3,)
        Odometry at the last filter update and now.
    scan : dict
        The scan at ``odom_now`` (see :func:`likelihood_field_model`).
    field : dict
        From :func:`likelihood_field`.
    params : dict
        See :data:`DEFAULT_PARAMS`; missing keys take the defaults.
    rng : numpy.random.Generator

    Returns
    -------
    particles : numpy.ndarray, shape (N, 3)
    weights : numpy.ndarray, shape (N,)
        Sum to 1 (all ``1/N`` right after resampling).
    updated : bool
        Whether the filter updated (False: the inputs are returned unchanged, as copies).
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_mcl_step(mcl_step)

# %% [markdown]
# ## 3.5 Global localization and tracking on the bag
#
# `mclplot.run_mcl` drives your `mcl_step` over the bag like AMCL's node does (the first scan forces an update,
# `odom_prev` is the odometry of the last update) and records the best hypothesis after each step: the
# weighted mean of the heaviest **cluster** of particles (`mclplot.estimate_pose`), not the mean of all
# particles, which would sit between the offices.
#
# Tracking uses $\alpha_i = 0.1$ (the odometry has a systematic bias that the model does not know, so the
# noise is larger than the simulator's), 60 beams and $\sigma_{hit} = 0.1$ m. Global localization needs a
# **smoother** model: $\sigma_{hit} = 0.3$ m, 30 beams and $\alpha_i = 0.3$. With the sharp tracking model the
# particles collapse within a second onto the first place that fits roughly, and the true place, which had
# no particle close enough yet, is lost for good (**particle deprivation**). Even so, global localization
# fails for some seeds (try `GLOBAL_SEED = 10`): the two extensions at the end of the lab address exactly that.

# %%
PARAMS = {"alphas": (0.1, 0.1, 0.1, 0.1), "z_hit": 0.9, "z_rand": 0.1, "max_beams": 60}  # tracking
GLOBAL_PARAMS = {"alphas": (0.3, 0.3, 0.3, 0.3), "z_hit": 0.9, "z_rand": 0.1, "max_beams": 30}
field_global = likelihood_field(grid, 0.3, MAX_DIST)
N_GLOBAL, N_TRACK, GLOBAL_SEED = 3000, 1000, 16

rng = np.random.default_rng(GLOBAL_SEED)
REPLAY_TIMES = sorted({*mclplot.SNAPSHOT_TIMES, *np.arange(0.0, data.t[-1], 5.0)})  # for the replay below
global_run = mclplot.run_mcl(data, mcl_step, init_uniform(grid, N_GLOBAL, rng), field_global, GLOBAL_PARAMS, rng,
                             every=2, desc="global localization", snapshot_times=REPLAY_TIMES)
mclplot.plot_snapshots(grid, global_run, title=f"Global localization: uniform start, {N_GLOBAL} particles",
                       times=[t for t in mclplot.SNAPSHOT_TIMES if t in global_run["snapshots"]]);

# %%
rng = np.random.default_rng(SEED)
start = init_gaussian(data.truth[0], np.diag([0.1**2, 0.1**2, 0.1**2]), N_TRACK, rng)
track_run = mclplot.run_mcl(data, mcl_step, start, field, PARAMS, rng, every=2, desc="tracking")
mclplot.plot_snapshots(grid, track_run, title=f"Tracking: Gaussian start around the true pose, {N_TRACK} particles");

# %%
mclplot.plot_errors({"global (uniform start)": global_run, "tracking (Gaussian start)": track_run}, skip=5.0,
                    title="Error of the best hypothesis against the ground truth");
late = track_run["t"] >= 5
print(f"tracking after 5 s: max position error {track_run['position_error'][late].max():.3f} m, "
      f"max heading error {np.rad2deg(track_run['heading_error'][late].max()):.1f} deg")
locked = mclplot.convergence_time(global_run, tolerance=0.5)
if locked is None:
    print("global localization: still more than 0.5 m off at the end of the run")
else:
    k = int(np.searchsorted(global_run["t"], locked))
    x, y = global_run["truth"][k, :2]
    print(f"global localization locks on at t = {locked:.1f} s (error below 0.5 m from then on), "
          f"with the robot at ({x:.1f}, {y:.1f}) m; before that the largest error is "
          f"{global_run['position_error'][:k].max():.1f} m")

# %% [markdown]
# The whole global run, replayed every 5 s (press play; the player steps frame by frame too):

# %%
from robolab.plotting.animation import animate_mcl, show_animation

show_animation(animate_mcl(grid, global_run))

# %% [markdown]
# **Try it.** The sliders rerun *your* `mcl_step` over the first 15 s of the bag, tracking from the true start
# pose, with another particle count and other motion-noise alphas (without Jupyter widgets: one figure at
# the defaults). How few particles still track? What do alphas of 0 do, and why?

# %%
from robolab.plotting.interactive import mcl_explorer

mcl_explorer(data, mcl_step, init_gaussian, field, PARAMS);


# %% [markdown]
# **The early jumps**: a common explanation of the big position jumps at the beginning of global
# localization is that the best hypothesis is inaccurate at first and gains confidence over time. Here the
# reason is more specific, and visible in the
# snapshots: the particles first gather in **several** places that explain the scans equally well (the four
# offices are identical), and the best hypothesis hops between those clusters until the robot sees something
# that breaks the symmetry; then the estimate jumps one last time, to the right place, and stays there. The
# cell above prints when that happens and where the robot is then: compare it with the map (which feature
# did the laser see?). Tracking never has this problem: it starts in the right office.
#
# **Questions**
#
# 1. Why does the global run need many more particles than tracking? What happens with 1000 particles from a
#    uniform start (try it)?
#
# *Your answer here.*
#
# 2. The likelihood of one scan is a product of 60 beam likelihoods, treated as independent. Is that true?
#    What does it do to the weights (look at `np.ptp` of the log-weights), and what could you do about it?
#
# *Your answer here.*
#
# 3. Set `update_min_d = 0.2`, `update_min_a = 0.5` (AMCL's defaults) and `resample_interval = 2`. What
#    changes in the error plot, and in run time?
#
# *Your answer here.*

# %% [markdown]
# ## Step beyond 1: KLD-sampling (AMCL's adaptive particle count)
#
# A tight cluster needs far fewer particles than a belief spread over four offices. **KLD-sampling**
# (Probabilistic Robotics **Table 8.4**, Fox 2003) draws particles until their number exceeds a bound that
# grows with the number $k$ of histogram bins they occupy (AMCL: 0.5 m x 0.5 m x 10 degrees):
#
# $$
# n = \left\lceil \frac{k-1}{2\varepsilon}\left(1 - \frac{2}{9(k-1)} + \sqrt{\frac{2}{9(k-1)}}\,z_{1-\delta}\right)^3 \right\rceil
# $$
#
# (the Wilson–Hilferty approximation of the $\chi^2_{k-1}$ quantile), so that with probability $1-\delta$ the
# Kullback–Leibler divergence between the particle approximation and the true posterior stays below
# $\varepsilon$. This is AMCL's `pf_resample_limit` (`kld_err` $=\varepsilon$, `kld_z` $= z$), clamped to
# `[min_particles, max_particles]`. (AMCL's default `kld_z = 0.99` is passed as the quantile itself; the
# 99 % quantile is 2.326.) One bin needs one particle. Accept an integer or an array of integers `k`.

# %% tags=["exercise"]
def kld_sample_size(k, epsilon, z):
    r"""Particles needed for KLD-sampling: the Wilson-Hilferty bound of Table 8.4.

    With :math:`k` histogram bins occupied, the number of samples such that,
    with probability :math:`1 - \delta`, the Kullback-Leibler divergence between
    the sample-based and the true posterior stays below :math:`\varepsilon` is

    .. math::

        n = \left\lceil \frac{k - 1}{2 \varepsilon}
            \left(1 - \frac{2}{9(k - 1)} + \sqrt{\frac{2}{9(k - 1)}}\, z_{1-\delta}\right)^3
            \right\rceil

    (Probabilistic Robotics, Table 8.4, line 14; Fox 2003). This is AMCL's
    ``pf_resample_limit`` with ``pop_err = epsilon`` (``kld_err``) and
    ``pop_z = z`` (``kld_z``) before its clamp to ``[min_particles,
    max_particles]``. (AMCL's default ``kld_z = 0.99`` is passed as the
    quantile itself; the 99 % quantile would be 2.326.) One bin needs one
    sample: ``kld_sample_size(1, ...) == 1``.

    Parameters
    ----------
    k : int or array_like of int
        Number of occupied bins, >= 1.
    epsilon : float
        Error bound, > 0.
    z : float
        Standard normal upper quantile :math:`z_{1-\delta}`, finite.

    Returns
    -------
    int or numpy.ndarray of int
        Same shape as ``k``.

    Raises
    ------
    TypeError
        ``k`` is not an integer number of bins or ``z`` not a number.
    ValueError
        ``k < 1``, ``epsilon <= 0`` (or so small that ``n`` overflows an int64) or
        a non-finite ``z``.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_kld_sample_size(kld_sample_size)

# %%
ks = np.arange(1, 400)
fig, ax = plt.subplots(figsize=(7, 3.5))
for eps, z in ((0.05, 2.326), (0.01, 2.326), (0.01, 0.99)):
    ax.plot(ks, kld_sample_size(ks, eps, z), label=f"epsilon = {eps}, z = {z}")
ax.set(title="KLD-sampling bound (Table 8.4)", xlabel="occupied bins k", ylabel="particles n", yscale="log")
ax.legend();

# %%
rng = np.random.default_rng(SEED)
kld_run = mclplot.run_kld(data, mcl_step, kld_sample_size, init_uniform(grid, 5000, rng), field_global,
                          GLOBAL_PARAMS, rng,
                          epsilon=0.05, z=2.326, n_min=200, n_max=5000, every=3)
mclplot.plot_particle_count(kld_run, title="KLD-sampling: particle count against time (global start)");
counts = np.asarray(kld_run["n_particles"])
at_min = kld_run["t"][np.argmax(counts <= 200)] if (counts <= 200).any() else None
print(f"particles per update: first {counts[0]}, median {int(np.median(counts))}, last {counts[-1]}; "
      + (f"down to n_min = 200 at t = {at_min:.1f} s" if at_min is not None else "never down to n_min"))
kld_locked = mclplot.convergence_time(kld_run, tolerance=0.5)
print("with KLD-sampling the estimate locks on " + (f"at t = {kld_locked:.1f} s" if kld_locked is not None
                                                     else "never (still off at the end)"))

# %% [markdown]
# Look at the printed numbers. KLD-sampling sets the count from how many bins the particles occupy *after*
# the update. With 60 beams treated as independent, one scan's likelihood is so peaked that a single
# resampling leaves the particles in a handful of bins, so the bound falls to `n_min` almost at once, even
# though the belief is still wrong (compare the lock-on time with that of the fixed 3000 particles above).
#
# **Question.** What would make the particle count adapt more gradually: fewer beams (`max_beams`), a
# tempered likelihood (the log-likelihood times a factor < 1), a larger $\varepsilon$, a larger `n_min`?
# Try one and report the printed numbers.
#
# *Your answer here.*


# %% [markdown]
# ## Step beyond 2: recovery from a kidnapping (augmented MCL)
#
# Once the particles have converged, nothing can bring them back if they are wrong: a **kidnapped** robot
# (carried elsewhere, or a wrong initial pose) stays lost. **Augmented MCL** (Table 8.3, AMCL's
# `recovery_alpha_slow` / `recovery_alpha_fast`) watches the average likelihood $w_{avg}$ with a slow and a
# fast exponential filter,
#
# $$
# w_{slow} \mathrel{+}= \alpha_{slow}(w_{avg} - w_{slow}), \qquad w_{fast} \mathrel{+}= \alpha_{fast}(w_{avg} - w_{fast}),
# $$
#
# and during resampling replaces each particle, with probability $\max(0, 1 - w_{fast}/w_{slow})$, by a random
# pose from `init_uniform`. When the scans suddenly fit badly, $w_{fast}$ drops below $w_{slow}$ and random
# particles are injected until one of them finds the robot.
#
# Use the per-beam geometric mean $p(z \mid x)^{1/K}$ ($K$ beams used) as the particle's likelihood in
# $w_{avg}$: the raw product of 60 beams changes by hundreds of orders of magnitude from scan to scan.
# Start with `w_slow = w_fast = 0` meaning "no history" (set both to $w_{avg}$ on the first step). Return
# `(particles, weights, w_slow, w_fast)`.

# %% tags=["exercise"]
def augmented_mcl_step(
    particles, weights, odom_prev, odom_now, scan, field, params, rng, grid, w_slow, w_fast
):
    r"""Augmented MCL with random-particle recovery: Probabilistic Robotics, Table 8.3.

    After the motion update and the weighting of :func:`mcl_step`, the average
    likelihood feeds two exponential filters (AMCL's ``recovery_alpha_slow``
    and ``recovery_alpha_fast``, :math:`0 \le \alpha_{slow} \ll \alpha_{fast}`):

    .. math::

        w_{avg} = \frac1N \sum_m \tilde w^{[m]}, \quad
        w_{slow} \mathrel{+}= \alpha_{slow}(w_{avg} - w_{slow}), \quad
        w_{fast} \mathrel{+}= \alpha_{fast}(w_{avg} - w_{fast}),

    and resampling replaces each particle, with probability
    :math:`\max(0, 1 - w_{fast} / w_{slow})`, by a pose drawn uniformly over the
    free space (:func:`init_uniform`); the others are drawn by low-variance
    resampling. A sudden drop of the likelihood (a kidnapping) makes
    :math:`w_{fast} < w_{slow}` and injects random particles until one of them
    finds the robot.

    The per-particle likelihood :math:`\tilde w` is tempered to the geometric
    mean over the :math:`K` beams used, :math:`\tilde w = p(z \mid x)^{1/K}`: the
    product of 60 beam likelihoods varies over hundreds of orders of magnitude
    from scan to scan, which would make :math:`w_{fast}/w_{slow}` jump on every
    scan (AMCL uses its own bounded score, :math:`1 + \sum_k p_k^3`, for the
    same reason). The step always updates and resamples (the thresholds of
    :func:`mcl_step` do not apply).

    Parameters
    ----------
    particles, weights, odom_prev, odom_now, scan, field, params, rng
        As for :func:`mcl_step`; ``params`` also holds ``alpha_slow`` and ``alpha_fast``.
    grid : robolab.maps.OccupancyGrid
        The map, for the random particles.
    w_slow, w_fast : float
        The filters' values from the previous step, >= 0; 0 at the start (the
        first step then sets both to :math:`w_{avg}` -- a 0 would be an
        infinitely bad history).

    Returns
    -------
    particles : numpy.ndarray, shape (N, 3)
    weights : numpy.ndarray, shape (N,)
        Uniform, ``1/N``.
    w_slow, w_fast : float
        Updated filter values.
    """
    # YOUR CODE HERE
    raise NotImplementedError



# %%
checks.check_augmented_mcl_step(augmented_mcl_step)

# %%
rng = np.random.default_rng(SEED)
recovery = {**PARAMS, "alpha_slow": 0.01, "alpha_fast": 0.2}
start = init_gaussian(data.truth[0], np.diag([0.05**2, 0.05**2, 0.05**2]), 1000, rng)
kidnap = mclplot.run_augmented(data, augmented_mcl_step, start, field, recovery, rng,
                               kidnap_at=30.0, kidnap_to=(15.0, 3.0, 1.0), every=2)
no_recovery = mclplot.run_augmented(data, augmented_mcl_step, start, field, {**recovery, "alpha_slow": 0.0,
                                    "alpha_fast": 0.0}, np.random.default_rng(SEED), kidnap_at=30.0,
                                    kidnap_to=(15.0, 3.0, 1.0), every=2, desc="no recovery")
fig = mclplot.plot_errors({"augmented MCL": kidnap, "plain MCL (alpha = 0)": no_recovery}, skip=30.0,
                          title="Kidnapped at t = 30 s: the filter is moved to (15, 3) m")
fig, ax = plt.subplots(figsize=(9, 2.5))
ax.plot(kidnap["t"], kidnap["random_fraction"])
ax.set(title="Fraction of random particles injected, 1 - w_fast / w_slow", xlabel="time [s]",
       ylabel="fraction");

# %% [markdown]
# **Questions**
#
# 4. How many particles does KLD-sampling use at the start, while the robot is in the office, and after it has
#    localized? Why?
#
# *Your answer here.*
#
# 5. After the kidnapping, how long does augmented MCL take to find the robot again, and what decides it?
#    What would happen with `alpha_fast` close to `alpha_slow`?
#
# *Your answer here.*

# %% [markdown]
# ## Step beyond 3: tracking a real Neato
#
# The Olin AC109 bag: a Neato robot with a backwards-mounted laser (beams without a return read 0), wheel
# odometry, and a ceiling camera's pose of the robot as ground truth, on a 2 cm map. The same `mcl_step` tracks it.
# The recording is not part of robolab; the cell says so when it is not on disk.

# %%
from robolab.datasets import DataSetUnavailable
from robolab.realdata.localization import NEATO_SCAN_DELAY, neato_localization

try:
    # The Neato's scans are stamped about 0.3 s late against its odometry and the camera:
    # odometry and truth are read that long before each scan's stamp.
    neato = neato_localization(scan_delay=NEATO_SCAN_DELAY)
except DataSetUnavailable as exc:
    neato = None
    print(exc)
else:
    neato_field = likelihood_field(neato.grid, 0.1, MAX_DIST)
    rng = np.random.default_rng(SEED)
    start = init_gaussian(neato.truth[0], np.diag([0.1**2, 0.1**2, 0.1**2]), 500, rng)
    neato_run = mclplot.run_mcl(neato, mcl_step, start, neato_field, PARAMS, rng, every=3, desc="Neato tracking")
    err = neato_run["position_error"]
    print(f"tracking the real Neato: median position error {np.median(err):.3f} m, "
          f"90 % {np.percentile(err, 90):.3f} m over {neato_run['t'][-1]:.0f} s")
    mclplot.plot_errors({"Neato, tracking": neato_run}, title="Tracking the real Neato in AC109");

# %% [markdown]
# And **global** localization on the real robot: a uniform start over the whole 2 cm map, the smoother
# `GLOBAL_PARAMS` of section 3.5, 2000 particles.

# %%
if neato is None:  # the recording read by the cell above (reading it again costs seconds)
    print("The Neato recording is not on disk (see the cell above).")
else:
    neato_global_field = likelihood_field(neato.grid, 0.3, MAX_DIST)
    rng = np.random.default_rng(GLOBAL_SEED)
    neato_global = mclplot.run_mcl(neato, mcl_step, init_uniform(neato.grid, 2000, rng), neato_global_field,
                                   GLOBAL_PARAMS, rng, every=2, desc="Neato global", snapshot_times=())
    locked = mclplot.convergence_time(neato_global, tolerance=0.5)
    err = neato_global["position_error"]
    print("global localization of the real Neato: "
          + (f"within 0.5 m from t = {locked:.1f} s on" if locked is not None else "not locked on at the end")
          + f"; median error over the second half {np.median(err[len(err) // 2:]):.3f} m, "
          f"final {err[-1]:.3f} m")

# %% [markdown]
# **Question.** The simulated bag tracked to a few centimetres; the printed error on the real robot is larger.
# Name two things in the real data that the simulator does not model, and what you would change in `PARAMS`.
#
# *Your answer here.*
