"""The rotation since the last update is not wrapped: 3.1 -> -3.1 counts as a 6.2 rad turn.

Angle wrapping far from 0 and near +-pi.

class: angle-wrap
"""

import math

import numpy as np

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
    turned = abs(now[2] - prev[2])
    min_d = check_positive("params['update_min_d']", prm["update_min_d"], allow_zero=True)
    min_a = check_positive("params['update_min_a']", prm["update_min_a"], allow_zero=True)
    if not prm["force_update"] and moved < min_d and turned < min_a:
        return p.copy(), w, False
    predicted = sample_motion_model_odometry(
        p, prev, now, prm["alphas"], rng, corrected=bool(prm["corrected"])
    )
    logw = likelihood_field_model(scan, predicted, field, prm)
    with np.errstate(divide="ignore"):
        w = normalize_log_weights(np.log(w) + logw)
    if (int(prm["update_count"]) + 1) % int(interval) == 0:
        predicted = low_variance_resample(predicted, w, rng)
        w = np.full(p.shape[0], 1.0 / p.shape[0])
    return predicted, w, True
