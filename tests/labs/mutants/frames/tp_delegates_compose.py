"""Turns each point into a pose (x, y, 0) and composes it with robolab.geometry.compose.

class: delegation
"""

import numpy as np

from robolab import geometry


def transform_points(points, pose):
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or np.shape(pose)[-1] != 3:
        raise ValueError("points must be (P, 2) and pose (3,) or (N, 3)")
    as_poses = np.column_stack([pts, np.zeros(len(pts))])
    pose = np.asarray(pose, dtype=float)
    if pose.ndim == 1:
        return geometry.compose(pose, as_poses)[:, :2]
    return np.stack([geometry.compose(p, as_poses)[:, :2] for p in pose])
