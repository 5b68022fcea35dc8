"""Divides by 1 - exp(-lambda z*) without guarding z* = 0 (0 / 0 at z* = 0).

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
    with np.errstate(divide="ignore", invalid="ignore"):
        eta = 1.0 / (1.0 - np.exp(-lambda_short * z_star))
    inside = (z >= 0.0) & (z <= z_star)
    return _out(np.where(inside, eta * lambda_short * np.exp(-lambda_short * z), 0.0))
