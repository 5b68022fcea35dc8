"""Squeezes its result: a scan with one hit beam gives a (2,) point instead of a (1, 2) array.

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.geometry import compose, transform_points
from solutions.odometry_mapping import _beam_kinds, _pose, _scan_arrays


def scan_endpoints(scan, pose, laser_offset):
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser_pose = compose(_pose("pose", pose), _pose("laser_offset", laser_offset))
    hit, _ = _beam_kinds(ranges, rmin, rmax)
    r, a = (ranges[hit], angles[hit])
    return np.squeeze(transform_points(np.stack([r * np.cos(a), r * np.sin(a)], -1), laser_pose))
