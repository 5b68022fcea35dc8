"""Squeezes its result: one particle gets a weight of shape () instead of (1,).

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.validation import as_array, as_poses, check_positive
from solutions.landmark_pf import LOG_FLOAT_MAX


def measurement_probability(measured_ranges, particles, landmarks, sensor_noise):
    lm = as_array("landmarks", landmarks, ndim=2, finite=True)
    if lm.shape[1] != 2:
        raise ValueError(f"landmarks must have shape (K, 2), got {lm.shape}")
    z = as_array("measured_ranges", measured_ranges, shape=(lm.shape[0],), finite=True)
    p = as_poses("particles", particles)
    sigma = check_positive("sensor_noise", sensor_noise)
    x, y = (p[:, 0], p[:, 1])
    sq = np.zeros(p.shape[0])
    for k in range(lm.shape[0]):
        r_hat = np.hypot(x - lm[k, 0], y - lm[k, 1])
        sq += (z[k] - r_hat) ** 2
    with np.errstate(over="ignore"):
        log_w = -0.5 * (sq / sigma) / sigma - lm.shape[0] * np.log(np.sqrt(2.0 * np.pi) * sigma)
    if np.any(log_w > LOG_FLOAT_MAX):
        raise ValueError(
            f"sensor_noise={sigma!r} is too small: the Gaussian density of the best particle, exp({log_w.max():.4g}), overflows float64"  # noqa: E501
        )
    return np.squeeze(np.exp(log_w))
