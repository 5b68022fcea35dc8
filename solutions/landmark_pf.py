"""Lab 03 reference solution: a particle filter in the cyclic landmark world.

Seed 002 (cWorld / cRobot, sections a to g, low-variance resampling). The
world is robolab's :class:`robolab.world.cWorld`: a cyclic 100 x 100 square
with four landmarks; the robot measures the range to every landmark.

Particles are an ``(N, 3)`` float array of poses ``(x, y, theta)``; every
function works on all particles at once (no Python loop over particles).
"""

from __future__ import annotations

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import (
    LOG_FLOAT_MAX,
    as_array,
    as_poses,
    check_count,
    check_finite,
    check_positive,
    check_rng,
)
from robolab.world import wrap_position

__all__ = ["move_particles", "measurement_probability", "low_variance_resample", "particle_filter"]


def move_particles(
    particles, u_rotation, u_translation, forward_noise, turn_noise, rng, world_size=100
):
    """Move every particle with the seed's noisy rotate-then-translate model.

    Seed 002, section b, for all particles at once; the rotation/translation
    motion model is Probabilistic Robotics' ``sample_motion_model_odometry``
    (Table 5.6) with no final rotation. For each particle ``i``, independently:

    .. math::

        \\theta_i' &= \\mathrm{wrap}(\\theta_i + u_{rot} + \\varepsilon_{\\theta,i}),
            \\quad \\varepsilon_{\\theta,i} \\sim \\mathcal N(0, \\sigma_{turn}^2) \\\\
        d_i &= u_{trans} + \\varepsilon_{d,i},
            \\quad \\varepsilon_{d,i} \\sim \\mathcal N(0, \\sigma_{fwd}^2) \\\\
        x_i' &= (x_i + d_i \\cos\\theta_i') \\bmod S, \\qquad
        y_i' = (y_i + d_i \\sin\\theta_i') \\bmod S

    One forward-noise sample per particle moves it along its new heading (the
    seed draws one for x and another for y, which is a bug). Headings are
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
    p = as_poses("particles", particles)
    if np.ndim(particles) != 2:
        raise ValueError(f"particles must have shape (N, 3), got {np.shape(particles)}")
    u_rot = check_finite("u_rotation", u_rotation)
    u_trans = check_finite("u_translation", u_translation)
    sigma_f = check_positive("forward_noise", forward_noise, allow_zero=True)
    sigma_t = check_positive("turn_noise", turn_noise, allow_zero=True)
    size = check_positive("world_size", world_size)
    check_rng(rng)
    n = p.shape[0]
    theta = wrap_angle(
        p[:, 2] + rng.normal(u_rot, sigma_t, size=n)
    )  # one turn-noise draw per particle
    d = rng.normal(u_trans, sigma_f, size=n)  # ONE forward-noise draw per particle
    out = np.empty_like(p)
    out[:, 0] = wrap_position(p[:, 0] + d * np.cos(theta), size)
    out[:, 1] = wrap_position(p[:, 1] + d * np.sin(theta), size)
    out[:, 2] = theta
    return out


def measurement_probability(measured_ranges, particles, landmarks, sensor_noise):
    """Likelihood of the measured ranges for every particle (seed 002, section d).

    The ranges to the ``K`` landmarks are independent given the pose, so their
    joint density is the product of Gaussian densities (Probabilistic Robotics,
    Table 6.4, with range only):

    .. math::

        w_i = p(z \\mid x_i, m) = \\prod_{k=1}^{K}
            \\frac{1}{\\sqrt{2\\pi}\\,\\sigma}
            \\exp\\!\\left(-\\frac{(z_k - \\hat r_{i,k})^2}{2\\sigma^2}\\right),
        \\qquad \\hat r_{i,k} = \\lVert (x_i, y_i) - l_k \\rVert

    ``r_hat`` is the plain Euclidean distance, **without** the cyclic wrap,
    exactly as the seed (and :meth:`robolab.world.cRobot.sense`) measures it.
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
    lm = as_array("landmarks", landmarks, ndim=2, finite=True)
    if lm.shape[1] != 2:
        raise ValueError(f"landmarks must have shape (K, 2), got {lm.shape}")
    z = as_array("measured_ranges", measured_ranges, shape=(lm.shape[0],), finite=True)
    p = as_poses("particles", particles)
    sigma = check_positive("sensor_noise", sensor_noise)
    x, y = p[:, 0], p[:, 1]
    sq = np.zeros(p.shape[0])  # sum_k (z_k - r_hat_k)^2 for every particle
    for k in range(lm.shape[0]):  # a loop over the K landmarks; each pass covers all particles
        # (an (N, K) broadcast would be ~20x slower: numpy's inner loop would run over only K = 4)
        r_hat = np.hypot(x - lm[k, 0], y - lm[k, 1])  # no overflow of the squares
        sq += (z[k] - r_hat) ** 2
    # The product of K Gaussians as one exp of the summed exponent:
    # prod_k N(z_k; r_k, s^2) = exp(-sum_k (z_k - r_k)^2 / (2 s^2)) / (sqrt(2 pi) s)^K
    # (sq / sigma) / sigma: sigma**2 underflows to 0 for sigma < 1e-162 (0 / 0 = NaN)
    with np.errstate(over="ignore"):  # a residual far beyond sigma: log weight -inf, weight 0
        log_w = -0.5 * (sq / sigma) / sigma - lm.shape[0] * np.log(np.sqrt(2.0 * np.pi) * sigma)
    if np.any(log_w > LOG_FLOAT_MAX):
        raise ValueError(
            f"sensor_noise={sigma!r} is too small: the Gaussian density of the best particle, "
            f"exp({log_w.max():.4g}), overflows float64"
        )
    return np.exp(log_w)


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
    p = as_array("particles", particles, ndim=2)
    n = p.shape[0]
    if n == 0:
        raise ValueError("particles must contain at least one particle")
    w = as_array("weights", weights, shape=(n,))
    lowest, highest = w.min(), w.max()  # NaN in either when any weight is NaN
    if not (lowest >= 0 and highest < np.inf):
        if not np.all(np.isfinite(w)):
            raise ValueError("weights must be finite (no NaN or inf)")
        raise ValueError(f"weights must be non-negative, got minimum {lowest}")
    with np.errstate(over="ignore"):  # weights near 1e308: rescaled below
        total = w.sum()
    if not total > 0:
        raise ValueError(
            "weights are all zero: cannot resample (every particle has zero likelihood)"
        )
    check_rng(rng)
    r = rng.uniform(0.0, 1.0 / n)
    if not np.isfinite(total):  # weights near 1e308 overflow the sum: scale them first
        w = w / w.max()
        total = w.sum()
    # c = cumsum(w / total) and the pointers r + m / N, each built in one array in place
    c = np.divide(w, total)
    np.cumsum(c, out=c)
    pointers = np.arange(n, dtype=float)
    pointers /= n
    pointers += r
    idx = np.searchsorted(c, pointers, side="right")
    # Rounding can leave c[-1] a hair below 1: never step past the last particle with weight.
    last = n - 1 if w[-1] > 0 else n - 1 - int(np.argmax(w[::-1] > 0))
    np.minimum(idx, last, out=idx)
    return np.take(p, idx, axis=0)  # a copy: no aliasing


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
    """The particle filter of seed 002, section g (Probabilistic Robotics Table 4.3).

    All particles start at the known ``initial_pose``. For every step ``t``:

    1. predict: ``x_t^[i] ~ p(x_t | u_t, x_{t-1}^[i])`` with :func:`move_particles`;
    2. weight: ``w_t^[i] = p(z_t | x_t^[i], m)`` with :func:`measurement_probability`;
    3. resample with :func:`low_variance_resample` (Table 4.4);
    4. estimate the position as the mean of the resampled, equally weighted
       particles, ``(mean x, mean y)`` (as the seed; the plain mean ignores the
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
        The known start ``(x, y, theta)``, default the seed's ``(10, 15, 0)``.
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
    lm, size = _landmarks_and_size(world, world_size)
    u = as_array("controls", controls, ndim=2, finite=True)
    if u.shape[1] != 2:
        raise ValueError(f"controls must have shape (T, 2), got {u.shape}")
    z = as_array("measurements", measurements, shape=(u.shape[0], lm.shape[0]), finite=True)
    n = check_count("n_particles", n_particles)
    sigma_f, sigma_t, sigma_s = _noise_triple(noise)
    start = as_array("initial_pose", initial_pose, shape=(3,), finite=True)
    check_rng(rng)

    steps = u.shape[0]
    particles = np.tile(start, (n, 1))
    path = np.empty((steps + 1, 2))
    path[0] = start[:2]
    if return_history:
        predicted = np.empty((steps, n, 3))
        weights_hist = np.empty((steps, n))
        resampled = np.empty((steps, n, 3))
    for t in range(steps):  # loop over time steps only; particles are vectorized
        particles = move_particles(particles, u[t, 0], u[t, 1], sigma_f, sigma_t, rng, size)
        w = measurement_probability(z[t], particles, lm, sigma_s)
        if return_history:
            predicted[t] = particles
            weights_hist[t] = w
        if not np.any(w > 0):
            w = np.ones(n)  # the filter is lost: keep the predicted cloud
        particles = low_variance_resample(particles, w, rng)
        if return_history:
            resampled[t] = particles
        path[t + 1] = particles[:, :2].mean(axis=0)
    if return_history:
        return {
            "path": path,
            "predicted": predicted,
            "weights": weights_hist,
            "resampled": resampled,
        }
    return path








def _noise_triple(noise):
    keys = ("forward_noise", "turn_noise", "sensor_noise")
    if isinstance(noise, dict):
        missing = [k for k in keys if k not in noise]
        if missing:
            raise ValueError(f"noise is missing {missing}; expected keys {list(keys)}")
        vals = [noise[k] for k in keys]
    else:
        vals = list(np.ravel(as_array("noise", noise)))
        if len(vals) != 3:
            raise ValueError(
                f"noise must be a dict with keys {list(keys)} or 3 numbers, got {len(vals)}"
            )
    f = check_positive("noise['forward_noise']", vals[0], allow_zero=True)
    t = check_positive("noise['turn_noise']", vals[1], allow_zero=True)
    s = check_positive("noise['sensor_noise']", vals[2])
    return f, t, s


def _landmarks_and_size(world, world_size):
    if hasattr(world, "landmarks") and hasattr(world, "size"):  # a cWorld
        return as_array("world.landmarks", world.landmarks, ndim=2, finite=True), check_positive(
            "world.size", world.size
        )
    lm = as_array("world", world, ndim=2, finite=True)
    if lm.shape[1] != 2:
        raise ValueError(
            f"world must be a cWorld or a (K, 2) array of landmarks, got shape {lm.shape}"
        )
    return lm, check_positive("world_size", world_size)
