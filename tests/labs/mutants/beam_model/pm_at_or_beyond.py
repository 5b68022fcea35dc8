"""Counts every reading at or beyond z_max as a max-range reading.

class: boundary
"""

from robolab.validation import check_positive
from solutions.beam_model import _out, _ranges


def p_max(z, z_max):
    z_max = check_positive("z_max", z_max)
    z = _ranges("z", z)
    return _out((z >= z_max).astype(float))
