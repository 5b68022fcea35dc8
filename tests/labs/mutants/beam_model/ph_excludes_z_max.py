"""Ends the hit support before z_max: a reading of exactly z_max gets 0 from p_hit.

class: boundary
"""

import numpy as np
from scipy.special import ndtr

from robolab.validation import check_positive
from solutions.beam_model import _broadcast, _check_expected, _out, _ranges


def p_hit(z, z_star, z_max, sigma_hit):
    z_max = check_positive("z_max", z_max)
    sigma_hit = check_positive("sigma_hit", sigma_hit)
    z, z_star = _broadcast(_ranges("z", z), _ranges("z_star", z_star))
    _check_expected(z_star, z_max)
    eta = 1.0 / (ndtr((z_max - z_star) / sigma_hit) - ndtr(-z_star / sigma_hit))
    u = (z - z_star) / sigma_hit
    gauss = np.exp(-0.5 * u * u) / (sigma_hit * np.sqrt(2.0 * np.pi))
    inside = (z >= 0.0) & (z < z_max)
    return _out(np.where(inside, eta * gauss, 0.0))
