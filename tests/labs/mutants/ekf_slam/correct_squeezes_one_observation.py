"""Squeezes the observations: a single observation (1, 3) becomes a (3,) row and is refused.

The smallest valid input, one observation, must keep its (k, 3) shape.

class: minimum-size
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import check_covariance
from solutions.ekf_slam import _belief, _observations, _observe


def correct(mu, sigma, observations, Qt):
    observations = (
        None if observations is None else np.squeeze(np.asarray(observations, dtype=float))
    )  # noqa: E501
    m, s = _belief(mu, sigma)
    obs = _observations(observations, (m.size - 3) // 2)
    qt = check_covariance("Qt", Qt, 2, definite=True)
    if len(obs) == 0:
        return (m.copy(), s.copy())
    z_hat, H = _observe(m, obs[:, 2].astype(np.intp))
    k = len(obs)
    e = obs[:, :2] - z_hat
    e[:, 1] = wrap_angle(e[:, 1])
    H = H.reshape(2 * k, -1)
    hs = H @ s
    S = hs @ H.T + np.kron(np.eye(k), qt)
    gain = np.linalg.solve(S, hs).T
    new_mu = m + gain @ e.reshape(-1)
    new_mu[2] = wrap_angle(new_mu[2])
    new_sigma = s - gain @ S @ gain.T
    return (new_mu, 0.5 * (new_sigma + new_sigma.T))
