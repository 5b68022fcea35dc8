"""Adds a new landmark from its first observation, then corrects with that same observation.

class: empty-map
"""

import numpy as np

from solutions.ekf_slam import _report, _steps, add_landmark, correct, predict


def ekf_slam(robot_or_run, R=None, Qt=None, history=False):
    steps, x0, k, r, qt = _steps(robot_or_run, R, Qt)
    mu = np.zeros(3 + 2 * k)
    mu[:3] = x0
    sigma = np.zeros((3 + 2 * k, 3 + 2 * k))
    seen = np.zeros(k, dtype=bool)
    means, covs = [mu], [sigma]
    for command, dt, motion, z in steps:
        mu, sigma = predict(mu, sigma, command, r, dt, motion)
        z = np.asarray(z, dtype=float).reshape(-1, 3)
        for row in z[~seen[z[:, 2].astype(int)]]:
            mu, sigma = add_landmark(mu, sigma, row[:2], int(row[2]), qt)
            seen[int(row[2])] = True
        mu, sigma = correct(mu, sigma, z, qt)
        means.append(mu)
        if history:
            covs.append(sigma)
    return _report(means, covs if history else None, sigma, seen)
