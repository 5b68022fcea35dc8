"""Lets the fiducial robot's own range-bearing model (robolab.fiducials) measure, pose by pose.

class: delegation
"""

import numpy as np

from robolab.fiducials import _range_bearing as fiducial_range_bearing
from solutions.fastslam import _last_dim


def h(landmark, pose):
    lm = _last_dim("landmark", landmark, 2)
    p = _last_dim("pose", pose, 3)
    shape = np.broadcast_shapes(lm.shape[:-1], p.shape[:-1])
    lm = np.broadcast_to(lm, shape + (2,)).reshape(-1, 2)
    p = np.broadcast_to(p, shape + (3,)).reshape(-1, 3)
    rows = [
        np.stack(fiducial_range_bearing(m[None, :], q), -1)[0] for m, q in zip(lm, p, strict=True)
    ]
    return np.array(rows).reshape(shape + (2,))
