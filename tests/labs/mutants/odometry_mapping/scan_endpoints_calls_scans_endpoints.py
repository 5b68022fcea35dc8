"""Lets the library's Scans.endpoints place the beams (it keeps the same hits).

class: delegation
"""

import numpy as np

from robolab.bag import Scans
from robolab.geometry import compose


def scan_endpoints(scan, pose, laser_offset):
    ranges = np.asarray(scan["ranges"], dtype=float)
    angles = np.asarray(scan["angles"], dtype=float)
    scans = Scans(
        np.zeros(1),
        ranges[None, :],
        angles,
        float(scan["range_min"]),
        float(scan["range_max"]),
        "laser",
    )
    pose = np.asarray(pose, dtype=float)
    laser_offset = np.asarray(laser_offset, dtype=float)
    if pose.shape != (3,) or laser_offset.shape != (3,):
        raise ValueError("pose and laser_offset must have shape (3,)")
    return scans.endpoints(0, compose(pose, laser_offset))
