"""Adds the heading to the beam angles although cast_rays adds the pose's heading already.

class: formula
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays
from robolab.validation import as_array
from solutions.beam_model import _check_params, _ranges, beam_range_finder_model


def pose_likelihood_map(scan, grid, beam_angles, params, positions, headings):
    prm = _check_params(params)
    if not isinstance(grid, OccupancyGrid):
        raise TypeError("grid must be an OccupancyGrid")
    scan = _ranges("scan", as_array("scan", scan, ndim=1))
    beam_angles = as_array("beam_angles", beam_angles, shape=(scan.shape[0],), finite=True)
    positions = as_array("positions", positions, ndim=2, finite=True)
    if positions.shape[1] != 2:
        raise ValueError("positions must have shape (P, 2)")
    headings = as_array("headings", headings, ndim=1, finite=True)
    out = np.empty((positions.shape[0], headings.shape[0]))
    for h, theta in enumerate(headings):
        poses = np.column_stack([positions, np.full(len(positions), theta)])
        z_star = cast_rays(grid, poses, wrap_angle(theta + beam_angles), prm["max_range"])
        out[:, h] = beam_range_finder_model(scan, z_star, prm, log=True)
    return out
