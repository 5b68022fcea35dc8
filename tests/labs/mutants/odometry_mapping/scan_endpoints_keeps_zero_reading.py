"""A zero reading is kept as a hit at the laser when range_min is 0 (no r > 0 test).

Boundary values of a validity interval (a zero reading when the lower bound is zero).

class: boundary
"""

import numpy as np

from robolab.geometry import compose, transform_points
from solutions.odometry_mapping import _pose, _scan_arrays


def scan_endpoints(scan, pose, laser_offset):
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser_pose = compose(_pose("pose", pose), _pose("laser_offset", laser_offset))
    with np.errstate(invalid="ignore"):
        hit = np.isfinite(ranges) & (ranges >= rmin) & (ranges < rmax)
    r, a = ranges[hit], angles[hit]
    return transform_points(np.stack([r * np.cos(a), r * np.sin(a)], -1), laser_pose)
