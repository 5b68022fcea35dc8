"""Reports the most likely predicted particle as the estimate, not the mean of the resampled cloud.

class: reported-estimate
"""

import numpy as np

from robolab.validation import as_array, check_count, check_rng
from solutions.landmark_pf import (
    _landmarks_and_size,
    _noise_triple,
    low_variance_resample,
    measurement_probability,
    move_particles,
)


def particle_filter(
    world,
    controls,
    measurements,
    n_particles,
    noise,
    rng,
    initial_pose=(10.0, 15.0, 0.0),
    world_size=100,
    return_history=False,
):
    lm, size = _landmarks_and_size(world, world_size)
    u = as_array("controls", controls, ndim=2, finite=True)
    if u.shape[1] != 2:
        raise ValueError(f"controls must have shape (T, 2), got {u.shape}")
    z = as_array("measurements", measurements, shape=(u.shape[0], lm.shape[0]), finite=True)
    n = check_count("n_particles", n_particles)
    sigma_f, sigma_t, sigma_s = _noise_triple(noise)
    start = as_array("initial_pose", initial_pose, shape=(3,), finite=True)
    check_rng(rng)

    steps = u.shape[0]
    particles = np.tile(start, (n, 1))
    path = np.empty((steps + 1, 2))
    path[0] = start[:2]
    if return_history:
        predicted = np.empty((steps, n, 3))
        weights_hist = np.empty((steps, n))
        resampled = np.empty((steps, n, 3))
    for t in range(steps):  # loop over time steps only; particles are vectorized
        particles = move_particles(particles, u[t, 0], u[t, 1], sigma_f, sigma_t, rng, size)
        w = measurement_probability(z[t], particles, lm, sigma_s)
        predicted_now = particles
        if return_history:
            predicted[t] = particles
            weights_hist[t] = w
        if not np.any(w > 0):
            w = np.ones(n)  # the filter is lost: keep the predicted cloud
        particles = low_variance_resample(particles, w, rng)
        if return_history:
            resampled[t] = particles
        path[t + 1] = predicted_now[int(np.argmax(w)), :2]
    if return_history:
        return {
            "path": path,
            "predicted": predicted,
            "weights": weights_hist,
            "resampled": resampled,
        }
    return path
