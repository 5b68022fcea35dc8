# ruff: noqa: F841, E501 -- a student mistake leaves a variable unused; lines as the student wrote them
"""W_avg is the mean of the raw scan likelihoods, not of the per-beam geometric means the text
defines.

Self-consistency with oracle values (running averages).

class: self-consistency
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
    w_avg = float(np.mean(np.exp(logw)))
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
