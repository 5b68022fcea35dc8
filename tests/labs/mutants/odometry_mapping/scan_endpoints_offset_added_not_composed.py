"""The laser offset is added to the pose component-wise instead of composed (not rotated by the
robot's heading).

Frames: pose composition.

class: formula
"""

import numpy as np

from robolab.geometry import transform_points
from solutions.odometry_mapping import _beam_kinds, _pose, _scan_arrays


def scan_endpoints(scan, pose, laser_offset):
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser_pose = _pose("pose", pose) + _pose("laser_offset", laser_offset)
    hit, _ = _beam_kinds(ranges, rmin, rmax)
    r, a = ranges[hit], angles[hit]
    return transform_points(np.stack([r * np.cos(a), r * np.sin(a)], -1), laser_pose)
