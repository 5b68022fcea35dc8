"""Does not check z_max: z_max <= 0 gives a negative or infinite density.

class: refusal
"""

import numpy as np

from solutions.beam_model import _out, _ranges


def p_rand(z, z_max):
    z_max = float(z_max)
    z = _ranges("z", z)
    return _out(np.where((z >= 0.0) & (z < z_max), 1.0 / z_max, 0.0))
