"""The new weights are the likelihoods alone, not the old weights times the likelihoods.

Non-uniform incoming weights (steps without resampling).

class: incoming-weights
"""

import math

import numpy as np

from robolab.geometry import angle_diff
from robolab.validation import as_array, as_poses, check_positive
from solutions.mcl import (
    _check_rng,
    _params,
    _weights,
    likelihood_field_model,
    low_variance_resample,
    normalize_log_weights,
    sample_motion_model_odometry,
)


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
        w = normalize_log_weights(logw)
    if (int(prm["update_count"]) + 1) % int(interval) == 0:
        predicted = low_variance_resample(predicted, w, rng)
        w = np.full(p.shape[0], 1.0 / p.shape[0])
    return predicted, w, True
