"""Relies on range_min alone: with range_min = 0 a reading of 0 becomes a point at the laser.

class: boundary
"""

import numpy as np

from robolab.validation import as_array, check_positive


def scan_to_cartesian(ranges, angles, range_min, range_max):
    ranges = as_array("ranges", ranges, ndim=1)
    angles = as_array("angles", angles, ndim=1, finite=True)
    if angles.shape != ranges.shape:
        raise ValueError("angles must hold one angle per range")
    rmin = check_positive("range_min", range_min, allow_zero=True)
    rmax = check_positive("range_max", range_max)
    if not rmin < rmax:
        raise ValueError("range_min must be < range_max")
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(ranges) & (ranges >= rmin) & (ranges < rmax)
    r, a = ranges[valid], angles[valid]
    return np.column_stack([r * np.cos(a), r * np.sin(a)])
