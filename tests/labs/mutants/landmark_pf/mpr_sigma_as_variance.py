"""Uses the sensor noise as the variance: exp(-e^2 / (2 sigma)).

class: formula
"""

import numpy as np

from robolab.validation import as_array, as_poses, check_positive


def measurement_probability(measured_ranges, particles, landmarks, sensor_noise):
    lm = as_array("landmarks", landmarks, ndim=2, finite=True)
    z = as_array("measured_ranges", measured_ranges, shape=(lm.shape[0],), finite=True)
    p = as_poses("particles", particles)
    sigma = check_positive("sensor_noise", sensor_noise)
    r_hat = np.hypot(p[:, None, 0] - lm[None, :, 0], p[:, None, 1] - lm[None, :, 1])
    return np.prod(np.exp(-0.5 * (z - r_hat) ** 2 / sigma) / np.sqrt(2 * np.pi * sigma), axis=1)
