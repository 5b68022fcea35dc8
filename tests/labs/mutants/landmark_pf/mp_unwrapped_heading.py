"""Does not wrap the new heading: it drifts out of [-pi, pi) after big turns.

class: angle-wrap
"""

import numpy as np

from robolab.validation import as_poses, check_positive, check_rng
from robolab.world import wrap_position


def move_particles(
    particles, u_rotation, u_translation, forward_noise, turn_noise, rng, world_size=100
):
    p = as_poses("particles", particles)
    sigma_f = check_positive("forward_noise", forward_noise, allow_zero=True)
    sigma_t = check_positive("turn_noise", turn_noise, allow_zero=True)
    size = check_positive("world_size", world_size)
    check_rng(rng)
    n = p.shape[0]
    theta = p[:, 2] + rng.normal(u_rotation, sigma_t, size=n)
    d = rng.normal(u_translation, sigma_f, size=n)
    out = np.empty_like(p)
    out[:, 0] = wrap_position(p[:, 0] + d * np.cos(theta), size)
    out[:, 1] = wrap_position(p[:, 1] + d * np.sin(theta), size)
    out[:, 2] = theta
    return out
