"""Compares with np.isclose: readings within 1e-8 relative of z_max count as max-range.

class: boundary
"""

import numpy as np

from robolab.validation import check_positive
from solutions.beam_model import _out, _ranges


def p_max(z, z_max):
    z_max = check_positive("z_max", z_max)
    z = _ranges("z", z)
    return _out((np.isclose(z, z_max)).astype(float))
