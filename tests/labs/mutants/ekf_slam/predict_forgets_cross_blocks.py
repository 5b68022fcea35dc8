"""Updates the pose block only: the pose-landmark cross-covariances are left as they were.

class: formula
"""

import numpy as np

from robolab.fiducials import DT
from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_covariance, check_positive
from solutions.ekf_slam import MOTIONS, _belief


def predict(mu, sigma, command, R, dt=DT, motion="unicycle"):
    m, s = _belief(mu, sigma)
    r = check_covariance("R", R, 3)
    if motion not in MOTIONS:
        raise ValueError(f"motion must be one of {MOTIONS}, got {motion!r}")
    theta = m[2]
    if motion == "unicycle":
        u = as_array("command", command, shape=(2,), finite=True)
        step = check_positive("dt", dt)
        dist, heading, turn = u[0] * step, theta, u[1] * step
    else:
        u = as_array("command", command, shape=(3,), finite=True)
        dist, heading, turn = u[1], theta + u[0], u[0] + u[2]
    new_mu = m.copy()
    new_mu[:3] += (dist * np.cos(heading), dist * np.sin(heading), turn)
    new_mu[2] = wrap_angle(new_mu[2])
    g = np.eye(3)
    g[0, 2], g[1, 2] = -dist * np.sin(heading), dist * np.cos(heading)
    new_sigma = s.copy()
    new_sigma[:3, :3] = g @ s[:3, :3] @ g.T + r
    return new_mu, new_sigma
