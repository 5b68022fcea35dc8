"""Does not check that there is one angle per range: extra ranges are silently paired with nothing.

class: refusal
"""

import numpy as np


def scan_to_cartesian(ranges, angles, range_min, range_max):
    ranges = np.asarray(ranges, dtype=float)
    angles = np.asarray(angles, dtype=float)
    if ranges.ndim != 1 or not 0 <= range_min < range_max:
        raise ValueError("ranges must be 1-D and 0 <= range_min < range_max")
    n = min(len(ranges), len(angles))
    ranges, angles = ranges[:n], angles[:n]
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(ranges) & (ranges > 0) & (ranges >= range_min) & (ranges < range_max)
    r, a = ranges[valid], angles[valid]
    return np.column_stack([r * np.cos(a), r * np.sin(a)])
