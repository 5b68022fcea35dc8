"""Adds Qt to the first observation's block only, as if the stacked noise were a single Qt.

class: formula
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import check_covariance
from solutions.ekf_slam import _belief, _observations, _observe


def correct(mu, sigma, observations, Qt):
    m, s = _belief(mu, sigma)
    obs = _observations(observations, (m.size - 3) // 2)
    qt = check_covariance("Qt", Qt, 2, definite=True)
    if len(obs) == 0:
        return m.copy(), s.copy()
    z_hat, H = _observe(m, obs[:, 2].astype(np.intp))
    k = len(obs)
    e = obs[:, :2] - z_hat
    e[:, 1] = wrap_angle(e[:, 1])
    H = H.reshape(2 * k, -1)
    hs = H @ s
    S = hs @ H.T
    S[:2, :2] += qt
    gain = np.linalg.solve(S, hs).T
    new_mu = m + gain @ e.reshape(-1)
    new_mu[2] = wrap_angle(new_mu[2])
    new_sigma = s - gain @ S @ gain.T
    return new_mu, 0.5 * (new_sigma + new_sigma.T)
