"""Lets the library's Scans.endpoints compute the endpoints.

class: delegation
"""

import numpy as np

from robolab.bag import Scans


def scan_to_cartesian(ranges, angles, range_min, range_max):
    ranges = np.asarray(ranges, dtype=float)
    if ranges.ndim != 1 or np.shape(angles) != ranges.shape or not 0 <= range_min < range_max:
        raise ValueError("one angle per range, and 0 <= range_min < range_max")
    return Scans([0.0], ranges[None], angles, range_min, range_max, "laser").endpoints(0)
