"""The covariances are a read-only broadcast view: every particle shares one 2 x 2 block.

In-place modification and aliasing.

class: aliasing
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_count
from solutions.fastslam import INIT_MODES, SIGMA0


def init_particles(n_particles, n_landmarks, x0, init="prior"):
    m = check_count("n_particles", n_particles)
    k = check_count("n_landmarks", n_landmarks)
    pose = as_array("x0", x0, shape=(3,), finite=True).copy()
    pose[2] = wrap_angle(pose[2])
    if init not in INIT_MODES:
        raise ValueError(f"init must be one of {INIT_MODES}, got {init!r}")
    return {
        "poses": np.tile(pose, (m, 1)),
        "means": np.zeros((m, k, 2)),
        "covs": np.broadcast_to(SIGMA0 * np.eye(2), (m, k, 2, 2)),
        "seen": np.full((m, k), init == "prior"),
        "weights": np.full(m, 1.0 / m),
    }
