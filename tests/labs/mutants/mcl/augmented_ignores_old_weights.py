"""The weights before resampling are the likelihoods alone, not old weights times likelihoods.

Non-uniform incoming weights.

class: incoming-weights
"""

import numpy as np

from robolab.validation import as_poses, check_positive
from solutions.mcl import (
    _check_rng,
    _params,
    _scan_arrays,
    _used_beams,
    _weights,
    init_uniform,
    likelihood_field_model,
    low_variance_resample,
    normalize_log_weights,
    sample_motion_model_odometry,
)


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
        w = normalize_log_weights(logw)
    resampled = low_variance_resample(predicted, w, rng)
    p_random = max(0.0, 1.0 - w_fast / w_slow) if w_slow > 0 else 0.0
    replace = rng.random(n) < p_random
    if replace.any():
        resampled[replace] = init_uniform(grid, int(replace.sum()), rng)
    return resampled, np.full(n, 1.0 / n), float(w_slow), float(w_fast)
