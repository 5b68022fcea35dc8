"""Spreads p_rand over the closed [0, z_max], so a max-range reading also gets 1 / z_max.

class: boundary
"""

import numpy as np

from solutions.beam_model import _out, _ranges


def p_rand(z, z_max):
    if not z_max > 0:
        raise ValueError("z_max must be > 0")
    z = _ranges("z", z)
    return _out(np.where((z >= 0.0) & (z <= z_max), 1.0 / z_max, 0.0))
