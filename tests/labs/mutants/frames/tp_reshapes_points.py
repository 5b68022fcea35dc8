"""Reshapes its input to (-1, 2): a single (2,) point or a (4, 3) array is transformed.

class: refusal
"""

import numpy as np


def transform_points(points, pose):
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    pose = np.asarray(pose, dtype=float)
    if pose.shape[-1] != 3:
        raise ValueError("pose must be (3,) or (N, 3)")
    c = np.cos(pose[..., 2])[..., None]
    s = np.sin(pose[..., 2])[..., None]
    x = pose[..., 0:1] + c * pts[:, 0] - s * pts[:, 1]
    y = pose[..., 1:2] + s * pts[:, 0] + c * pts[:, 1]
    return np.stack([x, y], axis=-1)
