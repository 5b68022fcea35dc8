"""Reports the predicted pose of each step, before the correction.

class: reported-estimate
"""

import numpy as np

from solutions.ekf_slam import _observe_step, _report, _steps, predict


def ekf_slam(robot_or_run, R=None, Qt=None, history=False):
    steps, x0, k, r, qt = _steps(robot_or_run, R, Qt)
    mu = np.zeros(3 + 2 * k)
    mu[:3] = x0
    sigma = np.zeros((3 + 2 * k, 3 + 2 * k))
    seen = np.zeros(k, dtype=bool)
    means, covs = [mu], [sigma]
    for command, dt, motion, z in steps:
        mu, sigma = predict(mu, sigma, command, r, dt, motion)
        predicted = mu
        mu, sigma = _observe_step(mu, sigma, z, seen, qt)
        means.append(predicted)
        if history:
            covs.append(sigma)
    return _report(means, covs if history else None, sigma, seen)
