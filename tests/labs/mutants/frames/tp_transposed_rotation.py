"""Uses the transposed rotation R(theta)^T (the inverse rotation).

class: formula
"""

import numpy as np

from robolab.validation import as_array


def transform_points(points, pose):
    pts = as_array("points", points, ndim=2, finite=True)
    if pts.shape[1] != 2:
        raise ValueError("points must have shape (P, 2)")
    pose = as_array("pose", pose, ndim=(1, 2), finite=True)
    if pose.shape[-1] != 3:
        raise ValueError("pose must be (3,) or (N, 3)")
    c = np.cos(pose[..., 2])[..., None]
    s = np.sin(pose[..., 2])[..., None]

    x = pose[..., 0:1] + c * pts[:, 0] + s * pts[:, 1]
    y = pose[..., 1:2] - s * pts[:, 0] + c * pts[:, 1]
    return np.stack([x, y], axis=-1)
