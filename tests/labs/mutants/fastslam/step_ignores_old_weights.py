"""The new weights are the step's likelihoods alone, not old weights times likelihoods.

Non-uniform incoming weights (steps without resampling).

class: incoming-weights
"""

import numpy as np

from robolab.fiducials import DT
from robolab.validation import check_covariance
from solutions.fastslam import (
    LOG_P0,
    _check_state,
    _ekf_update,
    _landmark_from_observation,
    _low_variance_resample,
    _normalize_log_weights,
    _observations,
    predict_poses,
)


def fastslam_step(state, command, observations, Q, Qt, rng, dt=DT, resample=True):
    s = _check_state(state)
    n_landmarks = s["means"].shape[1]
    obs = _observations(observations, n_landmarks)
    qt = check_covariance("Qt", Qt, 2, definite=True)
    poses = predict_poses(s["poses"], command, Q, rng, dt)  # checks command, Q, rng, dt
    means, covs, seen = s["means"].copy(), s["covs"].copy(), s["seen"].copy()
    log_w = np.zeros(len(s["weights"]))
    ids = obs[:, 2].astype(np.intp)
    remaining = np.arange(len(obs))
    while remaining.size:  # rounds of distinct landmark ids (one round unless ids repeat)
        _, first = np.unique(ids[remaining], return_index=True)
        batch, remaining = remaining[first], np.delete(remaining, first)
        j, z = ids[batch], obs[batch, :2]
        mu, sigma, known = means[:, j], covs[:, j], seen[:, j]  # (M, b, 2), (M, b, 2, 2), (M, b)
        new_mu, new_sigma, log_like = _ekf_update(mu, sigma, z[None], poses[:, None, :], qt)
        if not known.all():
            init_mu, init_sigma = _landmark_from_observation(z[None], poses[:, None, :], qt)
            new_mu = np.where(known[..., None], new_mu, init_mu)
            new_sigma = np.where(known[..., None, None], new_sigma, init_sigma)
            log_like = np.where(known, log_like, LOG_P0)
        means[:, j], covs[:, j], seen[:, j] = new_mu, new_sigma, True
        log_w = log_w + log_like.sum(axis=1)
    weights = _normalize_log_weights(log_w)
    new = {"poses": poses, "means": means, "covs": covs, "seen": seen, "weights": weights}
    if resample and len(obs):
        idx = _low_variance_resample(weights, rng)
        new = {key: value[idx] for key, value in new.items() if key != "weights"}
        new["weights"] = np.full(len(idx), 1.0 / len(idx))
    return new
