"""Squeezes its result: one particle comes back as a (3,) pose instead of a (1, 3) array.

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.fiducials import sqrt_psd
from robolab.validation import as_array, check_covariance, check_positive, check_rng
from solutions.fastslam import DT, _poses, _sample_motion


def predict_poses(poses, command, Q, rng, dt=DT):
    p = _poses(poses)
    u = as_array("command", command, shape=(2,), finite=True)
    q = check_covariance("Q", Q, 3, definite=False)
    check_rng(rng)
    dt = check_positive("dt", dt)
    return np.squeeze(_sample_motion(p, u, sqrt_psd(q), rng, dt))
