"""Forgets the upper end of the short support: readings beyond z* keep the exponential density.

class: boundary
"""

import numpy as np

from robolab.validation import check_positive
from solutions.beam_model import _broadcast, _out, _ranges


def p_short(z, z_star, lambda_short):
    lambda_short = check_positive("lambda_short", lambda_short)
    z, z_star = _broadcast(_ranges("z", z), _ranges("z_star", z_star))
    if np.any(z_star < 0):
        raise ValueError("z_star must be >= 0")
    mass = -np.expm1(-lambda_short * z_star)
    eta = np.divide(1.0, mass, out=np.zeros_like(mass), where=mass > 0)
    inside = z >= 0.0
    return _out(np.where(inside, eta * lambda_short * np.exp(-lambda_short * z), 0.0))
