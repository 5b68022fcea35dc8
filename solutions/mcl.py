r"""Lab 05, Monte Carlo localization on a bag: odometry motion model and likelihood field.

Reference solutions for ``notebooks/05_mcl.ipynb`` (seed 004, part 3; seed 000,
sections 1.2 and 2: AMCL's parameters, its odometry models and
``pf_update_resample``). Probabilistic Robotics: Table 5.6 (odometry motion
model), Table 6.3 (likelihood field), Table 4.4 (low-variance resampling),
Table 8.2 (MCL), Table 8.3 (augmented MCL) and Table 8.4 (KLD-sampling).

Data conventions
----------------
* A particle set is an ``(N, 3)`` float array of poses ``(x, y, theta)`` in
  the map frame (metres, radians, theta wrapped to ``[-pi, pi)``); weights are
  ``(N,)`` and sum to 1.
* An odometry reading is a pose ``(x, y, theta)`` of ``base_link`` in ``odom``.
* A scan is a dict ``{"ranges": (B,), "angles": (B,), "range_min": float,
  "range_max": float}`` in the laser frame, as ``sensor_msgs/LaserScan``.
* A likelihood field is the dict returned by :func:`likelihood_field`.
* ``params`` is a dict; :data:`DEFAULT_PARAMS` lists every key and its default.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import ndimage

from robolab.fieldsum import pose_table_sum
from robolab.geometry import angle_diff, wrap_angle
from robolab.maps import OccupancyGrid
from robolab.tablecache import cached_table, freeze
from robolab.validation import LOG_FLOAT_MAX, as_array, as_poses, check_positive
from solutions.landmark_pf import low_variance_resample  # lab 03's, reused (Table 4.4)

__all__ = [
    "DEFAULT_PARAMS",
    "init_uniform",
    "init_gaussian",
    "sample_motion_model_odometry",
    "likelihood_field",
    "likelihood_field_model",
    "normalize_log_weights",
    "low_variance_resample",
    "mcl_step",
    "kld_sample_size",
    "augmented_mcl_step",
]

#: AMCL's guard: below this translation (metres) the motion is an in-place rotation and rot1 = 0.
IN_PLACE_TRANSLATION = 0.01

#: sample_motion_model_odometry moves this many particles at a time (its temporaries stay in cache).
MOTION_BLOCK = 1 << 13

#: Every ``params`` key used by this lab, with AMCL-like defaults (seed 000, listing 1.2).
DEFAULT_PARAMS = {
    # motion model (Table 5.6): alpha1..alpha4, AMCL's odom_alpha1..4
    "alphas": (0.05, 0.05, 0.05, 0.05),
    "corrected": False,  # AMCL's ODOM_MODEL_DIFF_CORRECTED when True
    # likelihood field model (Table 6.3)
    "z_hit": 0.95,
    "z_rand": 0.05,
    "laser_pose": (0.0, 0.0, 0.0),  # base_link -> laser frame
    "max_beams": None,  # AMCL's laser_max_beams; None = every beam
    # filter (AMCL's update_min_d, update_min_a, resample_interval)
    "update_min_d": 0.0,
    "update_min_a": 0.0,
    "resample_interval": 1,
    "update_count": 0,  # filter updates done before this step (for resample_interval)
    "force_update": False,  # update even without motion (AMCL does on the first scan)
    # augmented MCL (Table 8.3): AMCL's recovery_alpha_slow / recovery_alpha_fast
    "alpha_slow": 0.001,
    "alpha_fast": 0.1,
}


# ----------------------------------------------------------------------------------------------
# 1. initialization
# ----------------------------------------------------------------------------------------------
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
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be a robolab.maps.OccupancyGrid, got {type(grid).__name__}")
    n = _count("n", n)
    _check_rng(rng)
    rows, cols = np.nonzero(grid.free)
    if rows.size == 0:
        raise ValueError("grid has no free cell to place particles in")
    pick = rng.integers(0, rows.size, n)
    # cell_to_world maps (row, col) to the centre; an offset in [-0.5, 0.5) spans the whole cell
    rc = np.stack([rows[pick], cols[pick]], -1) + rng.uniform(-0.5, 0.5, (n, 2))
    xy = grid.cell_to_world(rc)
    theta = wrap_angle(rng.uniform(-np.pi, np.pi, n))
    return np.column_stack([xy, theta])


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
    mu = as_array("pose", pose, shape=(3,), finite=True)
    sigma = as_array("cov", cov, shape=(3, 3), finite=True)
    n = _count("n", n)
    _check_rng(rng)
    scale = max(1.0, float(np.abs(sigma).max()))
    if not np.allclose(sigma, sigma.T, atol=1e-12 * scale, rtol=0):
        raise ValueError("cov must be symmetric")
    evals, evecs = np.linalg.eigh(sigma)
    if evals.min() < -1e-12 * scale:
        raise ValueError(f"cov must be positive semi-definite, got eigenvalue {evals.min():.3g}")
    root = evecs * np.sqrt(np.clip(evals, 0.0, None))  # root @ root.T == cov
    out = mu + rng.standard_normal((n, 3)) @ root.T
    out[:, 2] = wrap_angle(out[:, 2])
    return out


# ----------------------------------------------------------------------------------------------
# 2. motion model
# ----------------------------------------------------------------------------------------------
def sample_motion_model_odometry(particles, odom_prev, odom_now, alphas, rng, corrected=False):
    r"""Move every particle by the odometry, with noise: Probabilistic Robotics, Table 5.6.

    The odometry motion from :math:`\bar x = (\bar x, \bar y, \bar\theta)`
    (``odom_prev``) to :math:`\bar x' ` (``odom_now``) is decomposed as

    .. math::

        \delta_{trans} = \sqrt{(\bar x' - \bar x)^2 + (\bar y' - \bar y)^2}, \quad
        \delta_{rot1} = \operatorname{atan2}(\bar y' - \bar y, \bar x' - \bar x) - \bar\theta, \quad
        \delta_{rot2} = \bar\theta' - \bar\theta - \delta_{rot1}

    (seed 004, eq. 11). AMCL's guard: when :math:`\delta_{trans} < 0.01` m
    the bearing of two nearly equal positions is noise, so
    :math:`\delta_{rot1} = 0` (an in-place rotation). Each particle gets its own
    noisy motion,

    .. math::

        \hat\delta_{rot1} &= \delta_{rot1}
            - \varepsilon(\alpha_1 \delta_{rot1}^2 + \alpha_2 \delta_{trans}^2) \\
        \hat\delta_{trans} &= \delta_{trans} - \varepsilon(\alpha_3 \delta_{trans}^2
                               + \alpha_4 \delta_{rot1}^2 + \alpha_4 \delta_{rot2}^2) \\
        \hat\delta_{rot2} &= \delta_{rot2}
            - \varepsilon(\alpha_1 \delta_{rot2}^2 + \alpha_2 \delta_{trans}^2)

    where :math:`\varepsilon(b^2)` is a zero-mean Gaussian of **variance**
    :math:`b^2`. (Seed 004's eq. 12 writes the noise as
    :math:`\varepsilon_{\alpha_1|\delta_{rot2}| + \alpha_2|\delta_{trans}|}`: without
    the squares, i.e. as a standard deviation -- which is what AMCL's plain
    ``ODOM_MODEL_DIFF`` does -- and with :math:`\delta_{rot2}` in the noise of
    :math:`\delta_{rot1}`; Table 5.6 uses variances and :math:`\delta_{rot1}`.)
    Then (eq. 13)

    .. math::

        x' = x + \hat\delta_{trans}\cos(\theta + \hat\delta_{rot1}), \quad
        y' = y + \hat\delta_{trans}\sin(\theta + \hat\delta_{rot1}), \quad
        \theta' = \theta + \hat\delta_{rot1} + \hat\delta_{rot2}.

    With ``corrected=True`` this is AMCL's ``ODOM_MODEL_DIFF_CORRECTED``
    (seed 000, listing 2.1): backward motion (:math:`\delta_{rot1} \approx \pm\pi`)
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
    p = as_poses("particles", particles)
    if np.ndim(particles) != 2:
        raise ValueError(f"particles must have shape (N, 3), got {np.shape(particles)}")
    a = as_array("alphas", alphas, shape=(4,), finite=True, nonnegative=True)
    _check_rng(rng)
    if not isinstance(corrected, (bool, np.bool_)):
        raise TypeError(f"corrected must be a bool, got {type(corrected).__name__}")
    rot1, trans, rot2 = _odometry_deltas(odom_prev, odom_now)
    if corrected:
        n1 = min(abs(angle_diff(rot1, 0.0)), abs(angle_diff(rot1, np.pi)))
        n2 = min(abs(angle_diff(rot2, 0.0)), abs(angle_diff(rot2, np.pi)))
    else:
        n1, n2 = rot1, rot2
    var = np.array(
        [
            a[0] * n1**2 + a[1] * trans**2,
            a[2] * trans**2 + a[3] * (n1**2 + n2**2),
            a[0] * n2**2 + a[1] * trans**2,
        ]
    )
    n, sd = p.shape[0], np.sqrt(var)
    out = np.empty((n, 3))
    rng.standard_normal(out=out)  # the draws of rng.standard_normal((N, 3)), in place
    # In blocks of particles, in place: whole (N,) temporaries (800 KB each at 100 000
    # particles) leave the cache and are page-faulted afresh on every call.
    scratch = np.empty((4, min(n, MOTION_BLOCK)))
    for i in range(0, n, MOTION_BLOCK):
        k = min(MOTION_BLOCK, n - i)
        part, done = p[i : i + k], out[i : i + k]
        # the same products as draws * sqrt(var), stored as (3, k): contiguous rows
        noise = np.multiply(done.T, sd[:, None], out=scratch[:3, :k])
        r1 = np.subtract(rot1, noise[0], out=noise[0])
        tr = np.subtract(trans, noise[1], out=noise[1])
        r2 = np.subtract(rot2, noise[2], out=noise[2])
        heading = np.add(part[:, 2], r1, out=r1)
        step = np.cos(heading, out=scratch[3, :k])
        step *= tr
        np.add(part[:, 0], step, out=done[:, 0])
        step = np.sin(heading, out=step)
        step *= tr
        np.add(part[:, 1], step, out=done[:, 1])
        done[:, 2] = wrap_angle(np.add(heading, r2, out=r2))
    return out


# ----------------------------------------------------------------------------------------------
# 3. measurement model
# ----------------------------------------------------------------------------------------------
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
        ``"sigma_hit"``, ``"max_dist"``: floats. Plain data only; the two
        arrays are read-only (:func:`robolab.tablecache.freeze`), which lets
        :func:`likelihood_field_model` reuse its per-cell table from step to step.

    Raises
    ------
    TypeError
        ``grid`` is not an OccupancyGrid.
    ValueError
        ``sigma_hit <= 0`` (or so small that the Gaussian's peak overflows) or
        ``max_dist <= 0``.
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be a robolab.maps.OccupancyGrid, got {type(grid).__name__}")
    sigma = _sigma_hit("sigma_hit", sigma_hit)
    dmax = check_positive("max_dist", max_dist)
    occupied = grid.occupied
    if occupied.any():
        dist = ndimage.distance_transform_edt(~occupied) * grid.resolution
        dist = np.minimum(dist, dmax)
    else:
        dist = np.full(grid.shape, dmax)
    # read-only: likelihood_field_model caches its per-cell table per (field, parameters)
    return {
        "distance": freeze(dist),
        "likelihood": freeze(_gaussian(dist, sigma)),
        "resolution": float(grid.resolution),
        "origin": np.array(grid.origin, dtype=float),
        "sigma_hit": sigma,
        "max_dist": dmax,
    }


def likelihood_field_model(scan, particles, field, params):
    r"""Log-likelihood :math:`\log p(z \mid x, m)` of a scan for every particle: Table 6.3.

    Each valid beam :math:`k` (range :math:`z^k`, angle :math:`\theta_k` in the
    laser frame) is projected from the laser's pose
    :math:`x_{laser} = x \oplus x_{laser}^{base}` (``params["laser_pose"]``):

    .. math::

        x_{z^k} = x_{laser} + z^k \cos(\theta_{laser} + \theta_k), \quad
        y_{z^k} = y_{laser} + z^k \sin(\theta_{laser} + \theta_k),

    looked up in the field (world -> cell with the map's resolution and origin,
    seed 004's detail 1), and scored with the mixture

    .. math::

        \log p(z \mid x, m) = \sum_k \log\Big( z_{hit}\, \mathcal N(d(x_{z^k}); 0, \sigma_{hit}^2)
                                             + \frac{z_{rand}}{z_{max}} \Big)

    with :math:`z_{max}` the scan's ``range_max``. Beams that are not real
    returns (NaN, inf, outside ``[range_min, range_max)``: max-range readings
    carry no position information, AMCL skips them) are skipped. An endpoint
    outside the map is scored as if at :math:`d_{max}` (seed 004's detail 2,
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
    p = as_poses("particles", particles)
    ranges, angles, _, rmax = _scan_arrays(scan)
    prm = _params(params)
    z_hit, z_rand = _mixture(prm)
    laser = as_array("params['laser_pose']", prm["laser_pose"], shape=(3,), finite=True)
    table, geometry = _model_table(field, z_hit, z_rand, rmax)
    use = _used_beams(ranges, scan, prm)
    if not use.any():
        return np.zeros(p.shape[0])
    # Endpoints in continuous map coordinates (cells). world_to_map is affine, so the
    # laser's map coordinates (compose(particle, laser_pose), then world_to_map) plus
    # each beam rotated by (heading - map yaw) / resolution equal world_to_map of the
    # endpoint; float32 halves the memory traffic. robolab.fieldsum does this per
    # particle: compiled in one fused pass, or in numpy in cache-sized blocks.
    r, a = ranges[use], angles[use]
    qx = (r * np.cos(a) / geometry.resolution).astype(np.float32)
    qy = (r * np.sin(a) / geometry.resolution).astype(np.float32)
    return pose_table_sum(table, p, laser, geometry, qx, qy)


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
    lw = as_array("logw", logw, ndim=1)
    if lw.size == 0:
        raise ValueError("logw must hold at least one log-weight")
    top = lw.max()  # NaN if any entry is NaN, +inf if any is +inf
    if np.isnan(top) or top == np.inf:
        raise ValueError("logw must not contain NaN or +inf")
    if not np.isfinite(top):
        raise ValueError("logw is -inf everywhere: every particle has zero weight")
    w = np.subtract(lw, top)  # one new array, changed in place
    np.exp(w, out=w)
    w /= w.sum()
    return w


# ----------------------------------------------------------------------------------------------
# 4. resampling (your lab-03 function) and the MCL step
# ----------------------------------------------------------------------------------------------


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
    p = as_poses("particles", particles)
    w = _weights(weights, p.shape[0])
    prm = _params(params)
    _check_rng(rng)
    interval = prm["resample_interval"]
    if isinstance(interval, bool) or not isinstance(interval, (int, np.integer)) or interval < 1:
        raise ValueError(f"params['resample_interval'] must be an integer >= 1, got {interval!r}")
    prev = as_array("odom_prev", odom_prev, shape=(3,), finite=True)
    now = as_array("odom_now", odom_now, shape=(3,), finite=True)
    moved = math.hypot(now[0] - prev[0], now[1] - prev[1])
    turned = abs(angle_diff(now[2], prev[2]))
    min_d = check_positive("params['update_min_d']", prm["update_min_d"], allow_zero=True)
    min_a = check_positive("params['update_min_a']", prm["update_min_a"], allow_zero=True)
    if not prm["force_update"] and moved < min_d and turned < min_a:
        return p.copy(), w, False
    predicted = sample_motion_model_odometry(
        p, prev, now, prm["alphas"], rng, corrected=bool(prm["corrected"])
    )
    logw = likelihood_field_model(scan, predicted, field, prm)
    with np.errstate(divide="ignore"):
        logw = np.add(np.log(w, out=w), logw, out=w)  # w is this step's own copy
    w = normalize_log_weights(logw)
    if (int(prm["update_count"]) + 1) % int(interval) == 0:
        predicted = low_variance_resample(predicted, w, rng)
        w = np.full(p.shape[0], 1.0 / p.shape[0])
    return predicted, w, True


# ----------------------------------------------------------------------------------------------
# 5. beyond the seed: KLD-sampling and augmented MCL
# ----------------------------------------------------------------------------------------------
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
    kk = np.asarray(k)
    if kk.dtype == bool or not np.issubdtype(kk.dtype, np.integer):
        if not (
            np.issubdtype(kk.dtype, np.floating)
            and np.all(np.isfinite(kk))
            and np.all(kk == np.round(kk))
        ):
            raise TypeError(f"k must be an integer number of bins, got {k!r}")
    kk = kk.astype(np.int64)
    if np.any(kk < 1):
        raise ValueError(f"k must be >= 1, got minimum {kk.min()}")
    eps = check_positive("epsilon", epsilon)
    try:
        zq = float(z)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"z must be a number, got {type(z).__name__}") from exc
    if not np.isfinite(zq):
        raise ValueError(f"z must be finite, got {z!r}")
    km1 = np.maximum(kk - 1, 1).astype(float)
    b = 2.0 / (9.0 * km1)
    with np.errstate(over="ignore"):
        n = np.ceil(km1 / (2.0 * eps) * (1.0 - b + np.sqrt(b) * zq) ** 3)
    n = np.where(kk == 1, 1.0, np.maximum(n, 1.0))
    if np.any(n >= 2.0**63):  # not representable as int64 (it would wrap to negative)
        raise ValueError(
            f"epsilon={epsilon!r} is too small: the bound needs {np.max(n):.3g} particles, "
            f"more than an int64 holds"
        )
    n = n.astype(np.int64)
    return int(n) if n.ndim == 0 else n


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
    p = as_poses("particles", particles)
    n = p.shape[0]
    w = _weights(weights, n)
    prm = _params(params)
    _check_rng(rng)
    a_slow = check_positive("params['alpha_slow']", prm["alpha_slow"], allow_zero=True)
    a_fast = check_positive("params['alpha_fast']", prm["alpha_fast"], allow_zero=True)
    if not a_slow <= a_fast <= 1:
        raise ValueError(f"need 0 <= alpha_slow <= alpha_fast <= 1, got {a_slow}, {a_fast}")
    w_slow = check_positive("w_slow", w_slow, allow_zero=True)
    w_fast = check_positive("w_fast", w_fast, allow_zero=True)
    predicted = sample_motion_model_odometry(
        p, odom_prev, odom_now, prm["alphas"], rng, corrected=bool(prm["corrected"])
    )
    logw = likelihood_field_model(scan, predicted, field, prm)
    k = int(_used_beams(_scan_arrays(scan)[0], scan, prm).sum())
    w_avg = float(np.mean(np.exp(logw / max(k, 1))))
    if w_slow == 0.0 or w_fast == 0.0:
        w_slow = w_fast = w_avg
    else:
        w_slow += a_slow * (w_avg - w_slow)
        w_fast += a_fast * (w_avg - w_fast)
    with np.errstate(divide="ignore"):
        w = normalize_log_weights(np.log(w) + logw)
    resampled = low_variance_resample(predicted, w, rng)
    p_random = max(0.0, 1.0 - w_fast / w_slow) if w_slow > 0 else 0.0
    replace = rng.random(n) < p_random
    if replace.any():
        resampled[replace] = init_uniform(grid, int(replace.sum()), rng)
    return resampled, np.full(n, 1.0 / n), float(w_slow), float(w_fast)


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------
def _check_rng(rng) -> None:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")


def _count(name, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < 1:
        raise ValueError(f"{name} must be >= 1, got {value}")
    return int(value)


def _weights(weights, n) -> np.ndarray:
    w = as_array("weights", weights, shape=(n,), finite=True, nonnegative=True)
    total = w.sum()
    if not total > 0:
        raise ValueError("weights must not all be zero")
    return w / total


def _params(params) -> dict:
    if not isinstance(params, dict):
        raise TypeError(f"params must be a dict, got {type(params).__name__}")
    unknown = set(params) - set(DEFAULT_PARAMS)
    if unknown:
        raise ValueError(
            f"params has unknown key(s) {sorted(unknown)}; known: {sorted(DEFAULT_PARAMS)}"
        )
    return {**DEFAULT_PARAMS, **params}


def _mixture(prm) -> tuple[float, float]:
    z_hit = check_positive("params['z_hit']", prm["z_hit"], allow_zero=True)
    z_rand = check_positive("params['z_rand']", prm["z_rand"], allow_zero=True)
    if z_hit + z_rand <= 0:
        raise ValueError("params['z_hit'] and params['z_rand'] must not both be 0")
    return z_hit, z_rand


def _odometry_deltas(odom_prev, odom_now) -> tuple[float, float, float]:
    """``(rot1, trans, rot2)`` of the odometry motion (Table 5.6, lines 2-4), in-place guarded."""
    prev = as_array("odom_prev", odom_prev, shape=(3,), finite=True)
    now = as_array("odom_now", odom_now, shape=(3,), finite=True)
    dx, dy = now[0] - prev[0], now[1] - prev[1]
    trans = math.hypot(dx, dy)
    rot1 = 0.0 if trans < IN_PLACE_TRANSLATION else angle_diff(math.atan2(dy, dx), prev[2])
    rot2 = angle_diff(angle_diff(now[2], prev[2]), rot1)
    return rot1, trans, rot2


def _scan_arrays(scan):
    if not isinstance(scan, dict):
        raise TypeError(
            "scan must be a dict with ranges, angles, range_min, range_max, "
            f"got {type(scan).__name__}"
        )
    missing = [k for k in ("ranges", "angles", "range_min", "range_max") if k not in scan]
    if missing:
        raise ValueError(f"scan is missing key(s) {missing}")
    ranges = as_array("scan['ranges']", scan["ranges"], ndim=1)
    angles = as_array("scan['angles']", scan["angles"], shape=ranges.shape, finite=True)
    rmin = check_positive("scan['range_min']", scan["range_min"], allow_zero=True)
    rmax = check_positive("scan['range_max']", scan["range_max"])
    if rmin >= rmax:
        raise ValueError(f"scan['range_min'] ({rmin}) must be < scan['range_max'] ({rmax})")
    return ranges, angles, rmin, rmax


def _used_beams(ranges, scan, prm) -> np.ndarray:
    """Mask of the beams the model scores: AMCL's beam subsampling, then real returns only."""
    rmin, rmax = float(scan["range_min"]), float(scan["range_max"])
    use = np.zeros(ranges.size, dtype=bool)
    max_beams = prm["max_beams"]
    if max_beams is None:
        use[:] = True
    else:
        max_beams = _count("params['max_beams']", max_beams)
        step = max(1, (ranges.size - 1) // max(max_beams - 1, 1))
        use[::step] = True
    with np.errstate(invalid="ignore"):
        return use & np.isfinite(ranges) & (ranges >= rmin) & (ranges < rmax)


def _model_table(field, z_hit, z_rand, rmax):
    """The per-cell log mixture of Table 6.3 over the padded field, and the field's geometry.

    ``log(z_hit N(d; 0, sigma^2) + z_rand / z_max)`` per cell, with a one-cell border
    scored as ``d = max_dist`` (off the map), float32. Building it touches every cell
    of the map, so it is cached per (distance array, parameters) when the field's
    distance array is read-only (:mod:`robolab.tablecache`; :func:`likelihood_field`
    returns it so): then a step costs in proportion to particles x beams only.
    """
    if not isinstance(field, dict):
        raise TypeError(f"field must be the dict from likelihood_field, got {type(field).__name__}")
    missing = [
        k for k in ("distance", "resolution", "origin", "sigma_hit", "max_dist") if k not in field
    ]
    if missing:
        raise ValueError(f"field is missing key(s) {missing}")
    sigma = _sigma_hit("field['sigma_hit']", field["sigma_hit"])
    dmax = check_positive("field['max_dist']", field["max_dist"])
    geometry = _field_geometry(field["resolution"], field["origin"])
    source = field["distance"]

    def build():
        dist = as_array("field['distance']", source, ndim=2, finite=True, nonnegative=True)
        padded = np.pad(dist, 1, constant_values=dmax)
        if z_rand > 0:  # log(z_hit N(d) + z_rand / z_max), never log(0)
            table = np.log(z_hit * _gaussian(padded, sigma) + z_rand / rmax)
        else:
            table = (math.log(z_hit) if z_hit > 0 else -np.inf) + _log_gaussian(padded, sigma)
        return table.astype(np.float32)  # half the memory for the random-access gather

    key = ("likelihood_field_model", sigma, dmax, z_hit, z_rand, rmax)
    if not isinstance(source, np.ndarray):
        return build(), geometry
    return cached_table(source, key, build), geometry


def _field_geometry(resolution, origin):
    """An empty grid with a field's geometry: robolab.maps does every cell <-> world conversion.

    Built once per geometry (:func:`_geometry_of`); anything that is not a plain
    number and a (3,) origin goes to ``OccupancyGrid`` as it is, which refuses it.
    """
    try:
        o = np.asarray(origin, dtype=float)
        key = (float(resolution), *o.tolist()) if o.shape == (3,) else None
    except (TypeError, ValueError):
        key = None
    if key is None:
        return OccupancyGrid(np.zeros((1, 1)), resolution, origin)
    return _geometry_of(*key)


@functools.lru_cache(maxsize=16)
def _geometry_of(resolution, x, y, theta):
    return OccupancyGrid(np.zeros((1, 1)), resolution, (x, y, theta))


def _sigma_hit(name, value) -> float:
    """A positive sigma whose Gaussian peak ``1 / (sqrt(2 pi) sigma)`` is a float64."""
    sigma = check_positive(name, value)
    if _log_gaussian(0.0, sigma) > LOG_FLOAT_MAX:
        raise ValueError(f"{name}={sigma!r} is too small: the Gaussian's peak overflows float64")
    return sigma


def _log_gaussian(d, sigma):
    return -0.5 * (d / sigma) ** 2 - math.log(math.sqrt(2.0 * math.pi) * sigma)


def _gaussian(d, sigma):
    return np.exp(_log_gaussian(d, sigma))
