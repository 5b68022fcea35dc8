"""Squeezes its result: a single reading z = [z0] gives a number instead of a (1,) array.

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.validation import check_positive
from solutions.beam_model import _broadcast, _check_expected, _hit_mass, _out, _ranges


def p_hit(z, z_star, z_max, sigma_hit):
    z_max = check_positive("z_max", z_max)
    sigma_hit = check_positive("sigma_hit", sigma_hit)
    z, z_star = _broadcast(_ranges("z", z), _ranges("z_star", z_star))
    _check_expected(z_star, z_max)
    mass = _hit_mass(z_star, z_max, sigma_hit)
    u = (z - z_star) / sigma_hit
    with np.errstate(over="ignore", divide="ignore"):
        gauss = np.exp(-0.5 * u * u) / (sigma_hit * np.sqrt(2.0 * np.pi))
        out = np.where((z >= 0.0) & (z <= z_max), gauss / mass, 0.0)
    if not np.all(np.isfinite(out)):
        raise ValueError(
            f"sigma_hit={sigma_hit!r} is too small: the Gaussian density overflows float64"
        )
    return np.squeeze(_out(out))
