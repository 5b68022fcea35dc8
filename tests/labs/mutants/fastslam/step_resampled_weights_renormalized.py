"""After resampling, the survivors keep their own weights (renormalized) instead of 1/M.

The resampled cloud already carries the weights; weighting it again counts them twice.
With one survivor the two agree: only a draw with several survivors tells them apart.

class: incoming-weights
"""

import numpy as np

from robolab.fiducials import DT
from robolab.validation import check_covariance
from solutions.fastslam import (
    LOG_P0,
    _check_state,
    _check_update,
    _ekf_update,
    _ess_fraction,
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
    log_w = np.log(s["weights"], out=np.full_like(s["weights"], -np.inf), where=s["weights"] > 0)
    ess = _ess_fraction(resample)
    # Work on copies of the observed landmarks' columns only; the full arrays are
    # copied once, at the end (gathered by the resampling indices when resampling).
    touched, cols = np.unique(obs[:, 2].astype(np.intp), return_inverse=True)
    means, covs, seen = s["means"][:, touched], s["covs"][:, touched], s["seen"][:, touched]
    ids = cols.reshape(-1)
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
        _check_update((new_mu, new_sigma, log_like), f"observations {obs[batch].tolist()}")
        means[:, j], covs[:, j], seen[:, j] = new_mu, new_sigma, True
        log_w = log_w + log_like.sum(axis=1)
    weights = _normalize_log_weights(log_w)
    do_resample = (
        bool(resample)
        and len(obs) > 0
        and (ess is None or 1.0 / np.sum(weights**2) < ess * len(weights))
    )
    idx = _low_variance_resample(weights, rng) if do_resample else slice(None)
    new = {"poses": poses[idx]}
    for key, part in (("means", means), ("covs", covs), ("seen", seen)):
        new[key] = s[key][idx].copy() if isinstance(idx, slice) else s[key][idx]
        new[key][:, touched] = part[idx]
    # the survivors keep their own weights, renormalized
    new["weights"] = weights[idx] / weights[idx].sum()
    return new
