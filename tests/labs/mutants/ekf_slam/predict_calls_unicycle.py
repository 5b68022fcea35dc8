"""Lets the library's unicycle step move the pose.

class: delegation
"""

import numpy as np

from robolab.fiducials import DT, unicycle
from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_covariance, check_positive
from solutions.ekf_slam import MOTIONS, _belief


def predict(mu, sigma, command, R, dt=DT, motion="unicycle"):
    m, s = _belief(mu, sigma)
    r = check_covariance("R", R, 3)
    if motion not in MOTIONS:
        raise ValueError(f"motion must be one of {MOTIONS}, got {motion!r}")
    theta = m[2]
    new_mu = m.copy()
    if motion == "unicycle":
        u = as_array("command", command, shape=(2,), finite=True)
        step = check_positive("dt", dt)
        dist, heading = u[0] * step, theta
        new_mu[:3] = unicycle(m[:3], u, step)
    else:
        u = as_array("command", command, shape=(3,), finite=True)
        dist, heading = u[1], theta + u[0]
        new_mu[:3] += (dist * np.cos(heading), dist * np.sin(heading), u[0] + u[2])
    new_mu[2] = wrap_angle(new_mu[2])
    g = np.eye(3)
    g[0, 2], g[1, 2] = -dist * np.sin(heading), dist * np.cos(heading)
    new_sigma = s.copy()
    new_sigma[:3, :3] = g @ s[:3, :3] @ g.T + r
    new_sigma[:3, 3:] = g @ s[:3, 3:]
    new_sigma[3:, :3] = new_sigma[:3, 3:].T
    return new_mu, new_sigma
