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
#     lab: beam_model
# ---

# %% [markdown]
# # Lab 02 — The beam model of a range finder, and the maze challenge
#
# A laser range finder sends out beams and reports, for each, the distance $z^k$ to the first
# thing the beam hits. A localization filter must answer: **how likely is this scan if the
# robot stood at pose $x_t$ in map $m$?** That number, $p(z_t \mid x_t, m)$, is the
# *measurement model*, and the **beam model** (Probabilistic Robotics, section 6.3, Table 6.1)
# is its classic form:
#
# 1. ray casting in the map predicts the *true* range $z^{k*}$ of each beam;
# 2. the measured $z^k$ is explained by a mixture of four sources of error:
#    (a) a correct range with Gaussian noise, (b) an unexpected object in front,
#    (c) a failure reported as the maximum range, (d) a random reading;
# 3. beams are independent given the pose, so the scan's likelihood is a product over beams.
#
# This lab builds the model step by step and ends with a **challenge** on the
# maze, then compares the exact model with the ad-hoc combination that ROS's AMCL uses
# (`BeamModel` in AMCL's `amcl_laser.cpp`).
#
# You write six functions: `p_hit`, `p_short`, `p_max`, `p_rand`, `beam_range_finder_model`
# and `pose_likelihood_map`. A check cell after each exercise tests your code on a worked
# example; the grader's hidden tests check more (normalization, the point mass, bad input,
# the maze). Units: metres and radians throughout.

# %%
import time

import matplotlib.pyplot as plt
import numpy as np
from scipy.integrate import quad
from scipy.special import ndtr

from robolab.checks import beam_model as checks
from robolab.geometry import wrap_angle
from robolab.maps import OccupancyGrid, load_maze
from robolab.plotting import beam_model as bplot
from robolab.raycast import cast_rays, castraysingle
from robolab.validation import as_array, check_positive

# %% [markdown]
# ## The parameters
#
# The book writes the four mixture weights as $z_{hit}, z_{short}, z_{max}, z_{rand}$, and
# also calls the sensor's maximum range $z_{max}$. To keep the two apart, a parameter
# dictionary uses the book's names for the **weights** and `"max_range"` for the **range**:
#
# | key | meaning |
# |---|---|
# | `z_hit`, `z_short`, `z_max`, `z_rand` | mixture weights, each $\ge 0$, summing to 1 |
# | `sigma_hit` | standard deviation of the measurement noise $\sigma_{hit}$ [m] |
# | `lambda_short` | rate $\lambda_{short}$ of unexpected objects [1/m] |
# | `max_range` | the sensor's maximum range $z_{max}$ [m] |
#
# The four density functions take the **range** as their `z_max` argument.

# %%
PARAMS = {
    "z_hit": 0.8,
    "z_short": 0.1,
    "z_max": 0.05,
    "z_rand": 0.05,
    "sigma_hit": 0.2,     # m
    "lambda_short": 0.5,  # 1/m
    "max_range": 5.0,     # m
}
Z_MAX = PARAMS["max_range"]
Z_STAR = 3.0  # the expected range used for the figures, m


# %% [markdown]
# ## (a) Measurement noise: $p_{hit}$
#
# A correct reading is the true range $z^{k*}$ plus Gaussian noise, **truncated** to the
# sensor's range $[0, z_{max}]$ (eq. 6.4-6.6):
#
# $$
# p_{hit}(z^k \mid x_t, m) = \begin{cases} \eta\, \mathcal{N}(z^k; z^{k*}, \sigma_{hit}^2) & 0 \le z^k \le z_{max} \\ 0 & \text{otherwise}\end{cases}
# \qquad
# \mathcal{N}(z; z^*, \sigma^2) = \frac{1}{\sqrt{2\pi\sigma^2}} e^{-\frac{(z - z^*)^2}{2\sigma^2}}
# $$
#
# Cutting the Gaussian loses the mass outside $[0, z_{max}]$; the normalizer $\eta$ puts it back:
#
# $$
# \eta^{-1} = \int_0^{z_{max}} \mathcal{N}(z; z^*, \sigma_{hit}^2)\, dz
# = \Phi\!\left(\frac{z_{max} - z^*}{\sigma_{hit}}\right) - \Phi\!\left(\frac{-z^*}{\sigma_{hit}}\right),
# $$
#
# with $\Phi$ the standard normal CDF (`scipy.special.ndtr`). Work on whole arrays: `z` and
# `z_star` broadcast against each other (no Python loops). Reject bad input with a
# `ValueError` that names the argument (`sigma_hit <= 0`, `z_star` outside $[0, z_{max}]$),
# e.g. with `robolab.validation.check_positive`.

# %% tags=["exercise"]
def p_hit(z, z_star, z_max, sigma_hit):
    r"""Correct range with local measurement noise: a Gaussian truncated to :math:`[0, z_{max}]`.

    Probabilistic Robotics, eq. 6.4-6.6:

    .. math::

        p_{hit}(z \mid x_t, m) =
        \begin{cases}
            \eta\, \mathcal{N}(z;\, z^*,\, \sigma_{hit}^2) & 0 \le z \le z_{max}\\
            0 & \text{otherwise}
        \end{cases}
        \qquad
        \mathcal{N}(z; z^*, \sigma^2) = \frac{1}{\sqrt{2\pi\sigma^2}}
            e^{-\frac{(z - z^*)^2}{2\sigma^2}},

    with the normalizer computed exactly through the standard normal CDF
    :math:`\Phi`:

    .. math::

        \eta^{-1} = \int_0^{z_{max}} \mathcal{N}(z; z^*, \sigma_{hit}^2)\, dz
                  = \Phi\!\left(\frac{z_{max} - z^*}{\sigma_{hit}}\right)
                    - \Phi\!\left(\frac{-z^*}{\sigma_{hit}}\right).

    Since :math:`z^* \in [0, z_{max}]`, :math:`\eta^{-1} > 0`, so the result is
    finite; it integrates to 1 over :math:`[0, z_{max}]`.

    Parameters
    ----------
    z : float or array_like
        Measured range(s), metres; finite. Readings outside :math:`[0, z_{max}]`
        get density 0.
    z_star : float or array_like
        Expected range(s) from ray casting, metres, in :math:`[0, z_{max}]`;
        broadcasts against ``z``.
    z_max : float
        The sensor's maximum range, metres (> 0).
    sigma_hit : float
        Standard deviation of the measurement noise, metres (> 0).

    Returns
    -------
    float or numpy.ndarray
        The density (1/metres), with the broadcast shape of ``z`` and ``z_star``
        (a float for scalar input).

    Raises
    ------
    ValueError
        ``z_max`` or ``sigma_hit`` not finite and > 0, ``z``/``z_star`` not
        finite, ``z_star`` outside :math:`[0, z_{max}]`, shapes that do not broadcast.
    TypeError
        A non-numeric argument.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_p_hit(p_hit)


# %% [markdown]
# ## (b) Unexpected objects: $p_{short}$
#
# People and furniture that are not in the map cause readings *shorter* than $z^{k*}$. The
# closer an object, the likelier it intercepts the beam, so the model is an exponential
# truncated to $[0, z^{k*}]$ (eq. 6.7-6.9):
#
# $$
# p_{short}(z^k \mid x_t, m) = \begin{cases} \eta\, \lambda_{short}\, e^{-\lambda_{short} z^k} & 0 \le z^k \le z^{k*} \\ 0 & \text{otherwise}\end{cases}
# \qquad
# \int_0^{z^{k*}} \lambda_{short} e^{-\lambda_{short} z}\, dz = 1 - e^{-\lambda_{short} z^{k*}}
# \;\Rightarrow\; \eta = \frac{1}{1 - e^{-\lambda_{short} z^{k*}}}.
# $$
#
# **Careful at $z^{k*} = 0$** (a pose inside a wall: ray casting returns 0): then $\eta$ is
# $1/0$. There is no room for an object in front of the wall, so define $p_{short} = 0$
# everywhere in that case — never return NaN. (`-np.expm1(-x)` computes $1 - e^{-x}$
# accurately for small $x$.)

# %% tags=["exercise"]
def p_short(z, z_star, lambda_short):
    r"""Unexpected objects in front of the expected one: an exponential on :math:`[0, z^*]`.

    Probabilistic Robotics, eq. 6.7-6.9:

    .. math::

        p_{short}(z \mid x_t, m) =
        \begin{cases}
            \eta\, \lambda_{short}\, e^{-\lambda_{short} z} & 0 \le z \le z^*\\
            0 & \text{otherwise}
        \end{cases}
        \qquad
        \eta = \frac{1}{1 - e^{-\lambda_{short} z^*}},

    since :math:`\int_0^{z^*} \lambda e^{-\lambda z} dz = 1 - e^{-\lambda z^*}`.
    The normalizer is evaluated as ``-1 / expm1(-lambda_short * z_star)``, which
    is accurate for small :math:`\lambda_{short} z^*`.

    **The limit** :math:`z^* = 0`: the sensor touches the obstacle (ray casting
    returns 0 for a pose inside an obstacle) and there is no room for an
    unexpected object in front of it. The interval :math:`[0, z^*]` is a single
    point, and ``p_short`` is defined to be 0 for every ``z`` (the pointwise
    limit of the density for every :math:`z > 0`), never NaN. The same holds
    whenever :math:`z^*` is so small (about 1e-308 m) that the density
    :math:`\eta \lambda_{short}` would overflow to infinity.

    Parameters
    ----------
    z : float or array_like
        Measured range(s), metres; finite.
    z_star : float or array_like
        Expected range(s), metres (>= 0); broadcasts against ``z``.
    lambda_short : float
        Rate of the exponential, 1/metres (> 0).

    Returns
    -------
    float or numpy.ndarray
        The density (1/metres), with the broadcast shape of ``z`` and ``z_star``.

    Raises
    ------
    ValueError
        ``lambda_short`` not finite and > 0, ``z``/``z_star`` not finite,
        ``z_star`` negative, shapes that do not broadcast.
    TypeError
        A non-numeric argument.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_p_short(p_short)


# %% [markdown]
# ## (c) Failures: $p_{max}$ and (d) random readings: $p_{rand}$
#
# Obstacles are sometimes missed altogether (glass, black surfaces, sunlight); the sensor then
# reports its maximum range. That is a **point mass** (eq. 6.10) — a probability, not a density:
#
# $$
# p_{max}(z^k \mid x_t, m) = I(z^k = z_{max}) = \begin{cases} 1 & z^k = z_{max} \\ 0 & \text{otherwise.}\end{cases}
# $$
#
# The comparison is exact: a real driver reports "no return" as `inf`, `NaN` or a value
# $\ge$ `range_max`; map those to exactly $z_{max}$ *before* they reach the model.
#
# Unexplained phantom readings are uniform over the range (eq. 6.11), on the half-open
# interval (the reading $z_{max}$ itself belongs to $p_{max}$):
#
# $$
# p_{rand}(z^k \mid x_t, m) = \begin{cases} \dfrac{1}{z_{max}} & 0 \le z^k < z_{max} \\ 0 & \text{otherwise.}\end{cases}
# $$

# %% tags=["exercise"]
def p_max(z, z_max):
    r"""Failures reported as a max-range reading: the point mass at :math:`z_{max}`.

    Probabilistic Robotics, eq. 6.10:

    .. math::

        p_{max}(z \mid x_t, m) = I(z = z_{max}) =
        \begin{cases} 1 & z = z_{max}\\ 0 & \text{otherwise.} \end{cases}

    This is a probability (of the discrete event "the reading is exactly
    :math:`z_{max}`"), not a density. The comparison is **exact**: a real
    sensor's "no return" readings (``inf``, ``NaN``, values ``>= range_max``)
    must be mapped to exactly ``z_max`` beforehand; a reading of
    ``z_max - 1e-12`` is not a max-range reading.

    Parameters
    ----------
    z : float or array_like
        Measured range(s), metres; finite.
    z_max : float
        The sensor's maximum range, metres (> 0).

    Returns
    -------
    float or numpy.ndarray
        1.0 where ``z == z_max``, else 0.0; the shape of ``z``.

    Raises
    ------
    ValueError
        ``z`` not finite, ``z_max`` not finite and > 0.
    TypeError
        A non-numeric argument.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_p_max(p_max)


# %% tags=["exercise"]
def p_rand(z, z_max):
    r"""Random, unexplained measurements: uniform on :math:`[0, z_{max})`.

    Probabilistic Robotics, eq. 6.11:

    .. math::

        p_{rand}(z \mid x_t, m) =
        \begin{cases} \dfrac{1}{z_{max}} & 0 \le z < z_{max}\\ 0 & \text{otherwise.} \end{cases}

    The interval is half-open: the reading :math:`z_{max}` itself belongs to
    :func:`p_max`.

    Parameters
    ----------
    z : float or array_like
        Measured range(s), metres; finite.
    z_max : float
        The sensor's maximum range, metres (> 0).

    Returns
    -------
    float or numpy.ndarray
        The density (1/metres), the shape of ``z``.

    Raises
    ------
    ValueError
        ``z`` not finite, ``z_max`` not finite and > 0.
    TypeError
        A non-numeric argument.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_p_rand(p_rand)

# %% [markdown]
# ### The four error models (Probabilistic Robotics, Figure 6.3)
#
# Each component for $z^* = 3$ m on $[0, z_{max}]$:

# %%
z = np.linspace(0.0, Z_MAX, 2001)  # includes z = Z_MAX exactly, for the point mass
components = {
    "p_hit": p_hit(z, Z_STAR, Z_MAX, PARAMS["sigma_hit"]),
    "p_short": p_short(z, Z_STAR, PARAMS["lambda_short"]),
    "p_max": p_max(z, Z_MAX),
    "p_rand": p_rand(z, Z_MAX),
}
bplot.plot_components(z, components, Z_STAR, Z_MAX)
plt.show()

# %% [markdown]
# ### Do the densities integrate to 1?
#
# $p_{hit}$, $p_{short}$ and $p_{rand}$ are densities over the reading, so each must integrate
# to 1 over $[0, z_{max}]$ — whatever $z^*$, $\sigma_{hit}$ and $\lambda_{short}$ are. Check
# numerically with `scipy.integrate.quad` (the `points` argument tells it where the integrand
# has a kink or a jump):

# %%
print(f"{'z*':>5} {'sigma':>6} {'lambda':>6} | {'int p_hit':>10} {'int p_short':>11} {'int p_rand':>10}")
for z_star, sigma, lam in [(0.0, 0.5, 0.5), (1.0, 0.2, 2.0), (3.0, 1.0, 0.1), (4.9, 0.3, 1.0), (5.0, 2.0, 5.0)]:
    i_hit = quad(lambda v: p_hit(v, z_star, Z_MAX, sigma), 0.0, Z_MAX, points=[z_star])[0]
    i_short = quad(lambda v: p_short(v, z_star, lam), 0.0, z_star)[0] if z_star > 0 else float("nan")
    i_rand = quad(lambda v: p_rand(v, Z_MAX), 0.0, Z_MAX)[0]
    print(f"{z_star:5.1f} {sigma:6.1f} {lam:6.1f} | {i_hit:10.6f} {i_short:11.6f} {i_rand:10.6f}")
print("(z* = 0: p_short has no support, it is 0 everywhere by definition)")


# %% [markdown]
# ## The beam range finder model (Table 6.1)
#
# ```
# 1:  Algorithm beam_range_finder_model(z_t, x_t, m):
# 2:      q = 1
# 3:      for k = 1 to K do
# 4:          compute z_t^k* for the measurement z_t^k using ray casting
# 5:          p = z_hit * p_hit(z_t^k | x_t, m) + z_short * p_short(z_t^k | x_t, m)
# 6:              + z_max * p_max(z_t^k | x_t, m) + z_rand * p_rand(z_t^k | x_t, m)
# 7:          q = q * p
# 8:      return q
# ```
#
# Your function receives the ray-cast ranges (line 4) as `z_star`, computes the mixture of
# lines 5-6 for **all beams at once**, and the product of line 7 over the last axis:
#
# $$
# q = \prod_{k=1}^K p^k, \qquad \log q = \sum_{k=1}^K \log p^k .
# $$
#
# Each $p^k$ is a density (per metre): above 1 near a good match, far below 1 a few
# $\sigma_{hit}$ off. The product of a few hundred of them leaves the range of doubles
# ($10^{-308}$ to $10^{308}$) and becomes exactly `0.0` (or `inf`). With `log=True` return
# $\log q$ as a **sum of per-beam logs**, which never underflows. Shapes: `z` is `(B,)` (one
# scan) or `(N, B)`; `z_star` is `(B,)` (one pose) or `(N, B)` (N poses); the result is a
# float for one pose and `(N,)` for N poses. Validate `params` (exactly the keys above,
# weights $\ge 0$ summing to 1, positive `sigma_hit`, `lambda_short`, `max_range`) and the
# ranges (finite, in $[0, z_{max}]$).

# %% tags=["exercise"]
def beam_range_finder_model(z, z_star, params, log=False):
    r"""Likelihood of a whole scan under the beam model (Probabilistic Robotics, Table 6.1).

    For each beam :math:`k` (Table 6.1, lines 5-6)

    .. math::

        p^k = z_{hit}\, p_{hit}(z^k) + z_{short}\, p_{short}(z^k)
            + z_{max}\, p_{max}(z^k) + z_{rand}\, p_{rand}(z^k),

    and, beams being independent given the pose (line 7),

    .. math::

        q = \prod_{k=1}^{K} p^k, \qquad \log q = \sum_{k=1}^{K} \log p^k.

    Each :math:`p^k` is a density (per metre): above 1 near a good match
    (up to :math:`z_{hit} / (\sigma_{hit}\sqrt{2\pi})`), far below 1 a few
    :math:`\sigma_{hit}` off. The product of a few hundred of them leaves the
    range of doubles (:math:`10^{-308}` to :math:`10^{308}`) and becomes 0.0 or
    inf; ``log=True`` returns :math:`\log q` as a sum of per-beam logs, so it
    stays finite and exact for any number of beams. A beam whose mixture itself
    is near underflow (below about :math:`10^{-280}`: possible only with
    :math:`z_{rand} = 0`, a reading far out in the Gaussian's tail) is
    recomputed with log-sum-exp from the log of each component, so even its
    log is exact rather than ``-inf``.

    Parameters
    ----------
    z : array_like, shape (B,) or (N, B)
        Measured ranges, metres, in :math:`[0, \text{max\_range}]`; max-range
        readings exactly ``params["max_range"]`` (see the module docstring).
    z_star : array_like, shape (B,) or (N, B)
        Expected ranges from ray casting, metres, in :math:`[0, \text{max\_range}]`;
        ``(N, B)`` evaluates one scan ``z`` (B,) against N poses, or N scans
        against N poses when ``z`` is ``(N, B)`` too.
    params : dict
        ``{"z_hit", "z_short", "z_max", "z_rand"}``: mixture weights, each
        >= 0, summing to 1; ``"sigma_hit"`` (m), ``"lambda_short"`` (1/m),
        ``"max_range"`` (m), each > 0. Exactly these keys.
    log : bool
        Return :math:`\log q` instead of :math:`q`.

    Returns
    -------
    float or numpy.ndarray, shape (N,)
        :math:`q` (or :math:`\log q`), a float for a single pose. It is 0
        (``-inf`` in log form) only when some beam is impossible under the
        model, e.g. with ``z_rand = 0``; never NaN.

    Raises
    ------
    ValueError
        Bad ``params`` (missing/unknown keys, negative weights, weights not
        summing to 1, non-positive sigma/lambda/range), ``z``/``z_star`` not
        finite or outside :math:`[0, \text{max\_range}]`, shapes other than
        ``(B,)``/``(N, B)`` or with different numbers of beams or poses.
    TypeError
        ``params`` not a dict, non-numeric input.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_beam_range_finder_model(beam_range_finder_model)

# %% [markdown]
# ### The final distribution
#
# The mixture for one beam with $z^* = 3$ m, the shape of the book's Figure 6.4.
# Its continuous part integrates to $1 - z_{max}$-weight over $[0, z_{max})$; the point mass at
# $z_{max}$ carries the rest.

# %%
z_cont = np.linspace(0.0, np.nextafter(Z_MAX, 0.0), 4001)  # [0, z_max): the continuous part
mixture = beam_range_finder_model(z_cont[:, None], np.full((z_cont.size, 1), Z_STAR), PARAMS)
bplot.plot_mixture(z_cont, mixture, Z_STAR, Z_MAX, PARAMS["z_max"])
plt.show()

one_beam = lambda v: beam_range_finder_model(np.array([v]), np.array([Z_STAR]), PARAMS)
continuous = quad(one_beam, 0.0, Z_MAX, points=[Z_STAR], limit=200)[0]  # the point z_max has measure 0
point_mass = one_beam(Z_MAX)
print(f"integral over [0, z_max) = {continuous:.6f}  (1 - z_max weight = {1 - PARAMS['z_max']:.6f})")
print(f"p(z = z_max)             = {point_mass:.5f}  (the z_max weight plus a negligible Gaussian tail)")

# %% [markdown]
# ## The challenge: the robot in the maze
#
# The challenge: *import the map, position the robot, read from the sensor, ray cast at
# the sensor's angles and position, compute the probabilities, output $q$.*
#
# `load_maze()` returns the bundled maze as an `OccupancyGrid` (5 cm cells, origin at the
# lower-left corner). Because the maze has no people or furniture in it, the maze parameters use a high $z_{hit}$ and
# small weights for the other sources; the lidar has 60 beams, 6 degrees apart, all around.

# %%
maze = load_maze()
MAZE_PARAMS = {
    "z_hit": 0.9, "z_short": 0.03, "z_max": 0.03, "z_rand": 0.04,
    "sigma_hit": 0.1, "lambda_short": 1.0, "max_range": 3.0,
}
BEAMS = np.deg2rad(np.arange(-180, 180, 6))  # 60 beam angles relative to the heading, rad
TRUE_POSE = np.array([5.52, 8.47, np.pi / 3])  # x [m], y [m], theta [rad]
print(f"maze: {maze.shape[1]} x {maze.shape[0]} cells of {maze.resolution} m, extent {maze.extent} m")


# %% [markdown]
# ### Reading the sensor: sampling from the beam model
#
# To *simulate* a scan, run the model forwards: for each beam pick a source with probabilities
# $(z_{hit}, z_{short}, z_{max}, z_{rand})$, then draw the reading from it — a Gaussian around
# $z^*$, an exponential on $[0, z^*]$ (by inverting its CDF,
# $z = -\ln(1 - u(1 - e^{-\lambda z^*}))/\lambda$), exactly $z_{max}$, or a uniform value.

# %%
def simulate_scan(z_star, params, rng):
    """One reading per beam drawn from the beam model's mixture, given the true ranges z_star (B,)."""
    z_star = np.asarray(z_star, dtype=float)
    zmax, lam = params["max_range"], params["lambda_short"]
    weights = [params[k] for k in ("z_hit", "z_short", "z_max", "z_rand")]
    source = rng.choice(4, size=z_star.shape, p=weights)
    hit = np.clip(z_star + params["sigma_hit"] * rng.standard_normal(z_star.shape), 0.0, np.nextafter(zmax, 0))
    short = -np.log1p(-rng.random(z_star.shape) * -np.expm1(-lam * z_star)) / lam
    rand = rng.uniform(0.0, zmax, z_star.shape)
    return np.choose(source, [hit, short, np.full(z_star.shape, zmax), rand])


rng = np.random.default_rng(13)
true_ranges = cast_rays(maze, TRUE_POSE, BEAMS, MAZE_PARAMS["max_range"])[0]
scan = simulate_scan(true_ranges, MAZE_PARAMS, rng)
print(f"{np.sum(scan == MAZE_PARAMS['max_range'])} max-range readings, "
      f"{np.sum(scan < true_ranges - 3 * MAZE_PARAMS['sigma_hit'])} clearly short ones")
bplot.plot_scan_on_map(maze, TRUE_POSE, scan, BEAMS, MAZE_PARAMS["max_range"], expected=true_ranges,
                       title="Simulated scan at the true pose (green) and ray-cast z* (blue)")
plt.show()

# %% [markdown]
# ### Ray casting, one beam at a time and all at once
#
# `robolab.raycast` provides `castraysingle(xc, yc, theta, map, lidarrange)`: one beam, in **pixel**
# units, with `theta` absolute (not relative to the heading). Looping over the beams with it
# gives the same ranges as `cast_rays(grid, poses, angles, max_range)`, which works in metres
# for many poses and beams at once:

# %%
res = maze.resolution
xc, yc, heading = TRUE_POSE[0] / res, TRUE_POSE[1] / res, TRUE_POSE[2]  # metres -> pixels
t0 = time.perf_counter()
z_star_loop = np.array([castraysingle(xc, yc, heading + a, maze, MAZE_PARAMS["max_range"] / res) for a in BEAMS]) * res
t1 = time.perf_counter()
z_star = cast_rays(maze, TRUE_POSE, BEAMS, MAZE_PARAMS["max_range"])[0]
t2 = time.perf_counter()
print(f"castraysingle loop: {1e3 * (t1 - t0):.1f} ms, cast_rays: {1e3 * (t2 - t1):.1f} ms, "
      f"max difference {np.max(np.abs(z_star_loop - z_star)):.2e} m")

q = beam_range_finder_model(scan, z_star, MAZE_PARAMS)
log_q = beam_range_finder_model(scan, z_star, MAZE_PARAMS, log=True)
print(f"q = p(z | x_true, m) = {q:.4g}   (log q = {log_q:.2f})")

# %% [markdown]
# $q$ is a density over 60 readings (units $\mathrm{m}^{-60}$ for the continuous part), so its
# absolute value means little; what matters is how it **compares across poses**. Moving the
# robot a little should lower it:

# %%
for offset in ([0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.2, 0.0, 0.0], [0.0, 0.0, 0.1], [0.0, 0.0, 0.5]):
    pose = TRUE_POSE + offset
    zs = cast_rays(maze, pose, BEAMS, MAZE_PARAMS["max_range"])[0]
    print(f"pose offset {offset}: log q = {beam_range_finder_model(scan, zs, MAZE_PARAMS, log=True):9.2f}")

# %% [markdown]
# ### Why logs: the product underflows
#
# A lidar with 0.5-degree resolution has 720 beams. Each $p^k$ is a density: near the truth
# it can exceed 1 (here $z_{hit}/(\sigma_{hit}\sqrt{2\pi}) \approx 3.6$ per metre), a few
# tenths of a metre off it is far below 1. The product of 720 such numbers leaves the range
# of doubles ($10^{-308}$ to $10^{308}$): at poses only 20 and 40 cm from the truth it is
# exactly `0.0`, while the sum of logs still ranks them.

# %%
dense_beams = np.deg2rad(np.arange(-180, 180, 0.5))
dense_true = cast_rays(maze, TRUE_POSE, dense_beams, MAZE_PARAMS["max_range"])[0]
dense_scan = simulate_scan(dense_true, MAZE_PARAMS, np.random.default_rng(3))
for offset in ([0.0, 0.0, 0.0], [0.2, 0.0, 0.0], [0.4, 0.0, 0.0]):
    zs = cast_rays(maze, TRUE_POSE + offset, dense_beams, MAZE_PARAMS["max_range"])[0]
    q = beam_range_finder_model(dense_scan, zs, MAZE_PARAMS)
    log_q = beam_range_finder_model(dense_scan, zs, MAZE_PARAMS, log=True)
    print(f"pose offset {offset}: q = {float(q)!r:24}  log q = {log_q:8.1f}")
print("Two different poses, both q = 0.0: a particle filter could not tell them apart "
      "(and if all particles underflow, normalizing the weights is 0/0).")


# %% [markdown]
# ## AMCL's ad-hoc combination (`BeamModel` in `amcl_laser.cpp`)
#
# ROS's AMCL computes, per beam, an **unnormalized** mixture
#
# $$
# p_z = z_{hit}\, e^{-\frac{(z - z^*)^2}{2\sigma_{hit}^2}} + [z < z^*]\, z_{short} \lambda_{short} e^{-\lambda_{short} z}
#     + [z = z_{max}]\, z_{max} + [z < z_{max}]\, \frac{z_{rand}}{z_{max}},
# $$
#
# and then, instead of $q = \prod_k p_z^k$, the ad-hoc
#
# $$
# p = 1 + \sum_k \left(p_z^k\right)^3 \qquad \text{("an ad-hoc weighting scheme for combining beam probs ... works well, though")}.
# $$
#
# It is a sum, so it can never underflow, and cubing emphasizes good beams. Let us compare
# the two on the maze: which poses does each rank highest?

# %%
def amcl_beam_weight(z, z_star, params):
    """AMCL's BeamModel weight 1 + sum_k pz_k^3 for scans z (B,) against poses z_star (N, B)."""
    zmax = params["max_range"]
    diff = z - z_star
    pz = params["z_hit"] * np.exp(-diff**2 / (2 * params["sigma_hit"] ** 2))
    pz += np.where(diff < 0, params["z_short"] * params["lambda_short"] * np.exp(-params["lambda_short"] * z), 0.0)
    pz += np.where(z == zmax, params["z_max"], 0.0)
    pz += np.where(z < zmax, params["z_rand"] / zmax, 0.0)
    return 1.0 + np.sum(pz**3, axis=-1)


# A particle set as in global localization: 5000 poses uniform over the free space, plus
# 50 poses around the truth (as if the filter had already found it).
rng = np.random.default_rng(7)
free = np.argwhere(maze.free)
xy = maze.cell_to_world(free[rng.choice(len(free), 5000)]) + rng.uniform(-0.025, 0.025, (5000, 2))
spread = np.array([0.1, 0.1, 0.05])  # m, m, rad
poses = np.vstack([np.column_stack([xy, rng.uniform(-np.pi, np.pi, 5000)]),
                   TRUE_POSE + spread * rng.standard_normal((50, 3))])
poses[:, 2] = wrap_angle(poses[:, 2])
z_star_all = cast_rays(maze, poses, BEAMS, MAZE_PARAMS["max_range"])
score_exact = beam_range_finder_model(scan, z_star_all, MAZE_PARAMS, log=True)
score_amcl = amcl_beam_weight(scan, z_star_all, MAZE_PARAMS)

K = 10
best_exact = poses[np.argsort(score_exact)[::-1][:K]]
best_amcl = poses[np.argsort(score_amcl)[::-1][:K]]
for name, best in (("exact log q", best_exact), ("AMCL 1 + sum pz^3", best_amcl)):
    dist = np.hypot(*(best[:, :2] - TRUE_POSE[:2]).T)
    print(f"{name:18s}: best pose {np.round(best[0], 2)}, top-{K} distances to the truth {np.round(dist, 2)} m")

# As particle weights: how much weight lands on the 50 poses near the truth (1% of the set),
# and the effective sample size 1 / sum(w^2) of the normalized weights.
w_exact = np.exp(score_exact - score_exact.max())  # normalizing from logs: subtract the max first
w_exact /= w_exact.sum()
w_amcl = score_amcl / score_amcl.sum()
for name, w in (("exact", w_exact), ("AMCL", w_amcl)):
    print(f"{name:5s}: weight on the 50 near poses {w[-50:].sum():.3f}, effective sample size {1 / np.sum(w**2):8.1f}")
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5), constrained_layout=True)
bplot.plot_top_poses(maze, {"exact log q": best_exact, "AMCL 1 + sum pz^3": best_amcl}, ax1, true_pose=TRUE_POSE,
                     zoom=0.6, title=f"Top {K} of {len(poses)} poses under each model (zoomed)")
bplot.plot_weight_profiles({"exact: exp(log q), normalized": w_exact, "AMCL: 1 + sum pz^3, normalized": w_amcl},
                           ax2, title="Particle weights sorted by size")
plt.show()


# %% [markdown]
# ## Where in the maze could the robot be?
#
# Evaluate the log-likelihood of the scan at every combination of candidate position and
# heading, with **one** call to `cast_rays` for all poses (no loop over poses or beams).
#
# A useful observation for speed: the ray from position $p$ in absolute direction
# $\phi = \theta_h + \alpha_k$ does not depend on which heading and beam produced $\phi$. With
# headings on the beams' angular lattice (here both are multiples of 6 degrees), many
# $(h, k)$ pairs share a direction, so you can cast each distinct direction once per position
# (`np.unique(..., return_inverse=True)` on the wrapped directions) and gather.

# %% tags=["exercise"]
def pose_likelihood_map(scan, grid, beam_angles, params, positions, headings):
    r"""Log-likelihood of one scan at every combination of candidate position and heading.

    For position :math:`p` and heading :math:`\theta_h`, the pose is
    :math:`x = (p_x, p_y, \theta_h)`; ray casting on ``grid`` gives the expected
    ranges :math:`z^{k*}(x)` of the beams at :math:`\theta_h + \alpha_k` and

    .. math::

        L[p, h] = \log p(z \mid x, m) = \sum_k \log p(z^k \mid z^{k*}(x))

    (:func:`beam_range_finder_model` with ``log=True``, Table 6.1). A heat map of
    :math:`\max_h L[p, h]` answers "where in the map could the robot be?".

    All poses are cast at once with :func:`robolab.raycast.cast_rays`. The ray
    from position :math:`p` in absolute direction :math:`\phi` does not depend
    on which heading and beam produced :math:`\phi`, so each distinct direction
    :math:`\operatorname{wrap}(\theta_h + \alpha_k)` (to within 1e-9 rad) is cast
    once per position: with headings on the beams' angular lattice (e.g. 60
    beams over 360 degrees and headings in multiples of 6 degrees) that is
    ``B`` rays per position instead of ``H * B``.

    A position inside an obstacle gets :math:`z^* = 0` for every beam (the
    ray-casting convention) and hence a very low, finite score.

    Parameters
    ----------
    scan : array_like, shape (B,)
        Measured ranges, metres, in ``[0, params["max_range"]]``.
    grid : OccupancyGrid
        The map.
    beam_angles : array_like, shape (B,)
        Beam angles relative to the robot's heading, radians.
    params : dict
        Beam model parameters, see :func:`beam_range_finder_model`.
    positions : array_like, shape (P, 2)
        Candidate positions ``(x, y)``, metres, world frame.
    headings : array_like, shape (H,)
        Candidate headings, radians.

    Returns
    -------
    numpy.ndarray, shape (P, H)
        ``L[p, h]``, the log-likelihood of the scan at pose
        ``(positions[p, 0], positions[p, 1], headings[h])``.

    Raises
    ------
    ValueError
        Shapes other than stated, non-finite values, ranges outside
        ``[0, max_range]``, bad ``params``.
    TypeError
        ``grid`` not an OccupancyGrid, ``params`` not a dict, non-numeric input.
    """
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_pose_likelihood_map(pose_likelihood_map)

# %%
# Candidates: a 10 cm lattice of positions (cell centres, walls included) and 12 headings.
xs, ys, positions = bplot.lattice_positions(maze, 0.1)
headings = np.deg2rad(np.arange(-180, 180, 30))
# On a 10 cm lattice the nearest candidate can be 7 cm from the truth; with sigma_hit = 10 cm
# that candidate loses tens of nats (see the pose offsets above) and the map is all speckle.
# Global search on a coarse lattice therefore inflates sigma_hit to the lattice's scale.
COARSE_PARAMS = dict(MAZE_PARAMS, sigma_hit=0.25)
t0 = time.perf_counter()
log_l = pose_likelihood_map(scan, maze, BEAMS, COARSE_PARAMS, positions, headings)
print(f"{log_l.size} poses x {BEAMS.size} beams in {time.perf_counter() - t0:.2f} s")

best = np.unravel_index(np.argmax(log_l), log_l.shape)
print(f"most likely pose: {positions[best[0]]}, heading {np.rad2deg(headings[best[1]]):.0f} deg "
      f"(truth: {TRUE_POSE[:2]}, {np.rad2deg(TRUE_POSE[2]):.0f} deg)")
bplot.plot_likelihood_map(maze, xs, ys, log_l.max(axis=1).reshape(ys.size, xs.size), true_pose=TRUE_POSE,
                          floor=100.0, title="Scan log-likelihood, best heading per position")
plt.show()

# %% [markdown]
# The heat map is clipped 100 nats below its maximum: everything black is at least $e^{100}$
# times less likely than the best pose. Corridors that *look alike* to the lidar (same widths,
# same turns) show up as secondary bright spots — the reason global localization needs many
# particles and several scans.

# %% [markdown]
# ### Try it: the mixture against the map
#
# The sliders rerun *your* `beam_range_finder_model` and `pose_likelihood_map` (on a 25 cm lattice,
# so that a redraw is quick; the weights are normalized to sum to 1). Without Jupyter widgets you see
# the figure at the defaults. Things to try: $z_{rand} \to 0$ with a small $\sigma_{hit}$ (what happens
# to the secondary spots, and to the true pose?); a large $z_{short}$ with a large $\lambda_{short}$.

# %%
from robolab.plotting.interactive import beam_model_explorer

beam_model_explorer(beam_range_finder_model, pose_likelihood_map, scan, maze, BEAMS, COARSE_PARAMS,
                    true_pose=TRUE_POSE);

# %% [markdown]
# ## Questions
#
# 1. The integrals above are 1 for every $z^*$, $\sigma_{hit}$ and $\lambda_{short}$. What
#    would go wrong in the mixture if you forgot $\eta$ in $p_{hit}$ when $z^*$ is close to 0
#    or to $z_{max}$?
#
# *Your answer here.*
#
# 2. $p_{max}$ is a probability while the other three are densities, yet Table 6.1 adds them.
#    What does that imply for a max-range reading's weight compared with a good hit when
#    $\sigma_{hit}$ is small? What must a driver do with `inf`/`NaN` readings before they reach
#    the model?
#
# *Your answer here.*
#
# 3. The maze parameters use a very high $z_{hit}$ and very low weights for unexpected
#    objects. When is that a good idea, and what happens to the localization when a person
#    walks past the robot with these weights?
#
# *Your answer here.*
#
# 4. Why does the product $q$ underflow for hundreds of beams, and why does it not matter for
#    a particle filter to work with $\log q$ instead? (How do you normalize weights given only
#    their logs?)
#
# *Your answer here.*
#
# 5. Compare the rankings of the exact model and AMCL's $1 + \sum_k (p_z^k)^3$. Which one would
#    you trust to resample a particle set, and why does AMCL's combination "work well, though"?
#    Which assumption of Table 6.1 does the ad-hoc rule quietly give up?
#
# *Your answer here.*
#
# 6. The heat map has more than one bright region. What would it take to decide between them?
#
# *Your answer here.*
