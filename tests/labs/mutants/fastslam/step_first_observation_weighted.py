"""A landmark seen for the first time weights the particle with the EKF likelihood of the
placeholder prior instead of p0.

Empty or partially known maps (first observation).

class: empty-map
"""

import numpy as np

from robolab.fiducials import DT
from robolab.validation import check_covariance
from solutions.fastslam import (
    _check_state,
    _ekf_update,
    _landmark_from_observation,
    _low_variance_resample,
    _normalize_log_weights,
    _observations,
    predict_poses,
)


def fastslam_step(state, command, observations, Q, Qt, rng, dt=DT, resample=True):
    r"""One step of FastSLAM 1.0 with known correspondences (Probabilistic Robotics Table 13.1).

    1. Sample each particle's pose from the motion model (:func:`predict_poses`).
    2. For every observation ``[r, phi, j]``, in every particle at once: if
       landmark j has a belief, EKF-update it (:func:`update_landmark`) and
       multiply the weight by the likelihood; otherwise initialize it from the
       observation, :math:`\mu = (x + r\cos(\theta+\phi), y + r\sin(\theta+\phi))`,
       :math:`\Sigma = H^{-1} Q_t H^{-T}`, weight factor :math:`p_0`. Landmarks not
       observed are left alone. Observations of different landmarks are
       processed together; a repeated id waits for the next round.
    3. Normalize the weights in log space:
       :math:`w_k = \exp(\ell_k - \max\ell) / \sum_i \exp(\ell_i - \max\ell)` with
       :math:`\ell_k = \ln w_k^{old} + \sum \ln \mathcal N(z; \hat z, Q)`, so the
       weights stay finite even when every likelihood underflows.
    4. Resample with the low-variance sampler (Table 4.4), unless ``resample``
       is False or there was no observation (then the weights did not change).
       Resampling copies the chosen particles' arrays (fancy indexing): no two
       particles share landmark memory, and the input ``state`` is not modified.

    Parameters
    ----------
    state : dict
        ``poses``, ``means``, ``covs``, ``seen``, ``weights`` as made by
        :func:`init_particles`.
    command : array_like, shape (2,)
        ``[v, omega]``.
    observations : array_like, shape (k, 3)
        Rows ``[range, bearing, id]`` (``k`` may be 0; ``None`` means none).
    Q : array_like, shape (3, 3)
        Motion noise covariance.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance.
    rng : numpy.random.Generator
    dt : float
        Time step in seconds.
    resample : bool
        Resample after weighting (the book always does). With False the new
        state keeps the normalized importance weights.

    Returns
    -------
    dict
        The new state (new arrays). After resampling the weights are uniform.
    """
    s = _check_state(state)
    n_landmarks = s["means"].shape[1]
    obs = _observations(observations, n_landmarks)
    qt = check_covariance("Qt", Qt, 2, definite=True)
    poses = predict_poses(s["poses"], command, Q, rng, dt)  # checks command, Q, rng, dt
    means, covs, seen = s["means"].copy(), s["covs"].copy(), s["seen"].copy()
    log_w = np.log(s["weights"], out=np.full_like(s["weights"], -np.inf), where=s["weights"] > 0)
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
        means[:, j], covs[:, j], seen[:, j] = new_mu, new_sigma, True
        log_w = log_w + log_like.sum(axis=1)
    weights = _normalize_log_weights(log_w)
    new = {"poses": poses, "means": means, "covs": covs, "seen": seen, "weights": weights}
    if resample and len(obs):
        idx = _low_variance_resample(weights, rng)
        new = {key: value[idx] for key, value in new.items() if key != "weights"}
        new["weights"] = np.full(len(idx), 1.0 / len(idx))
    return new
