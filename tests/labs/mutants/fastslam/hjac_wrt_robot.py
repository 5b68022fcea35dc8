"""The Jacobian with respect to the robot's position (the landmark's, negated).

Where a Jacobian is evaluated (with respect to what).

class: jacobian-point
"""

import numpy as np

from solutions.fastslam import MIN_SQ_RANGE, _last_dim


def h_jacobian(landmark, pose):
    lm, p = _last_dim("landmark", landmark, 2), _last_dim("pose", pose, 3)
    dx = lm[..., 0] - p[..., 0]
    dy = lm[..., 1] - p[..., 1]
    q = np.maximum(dx * dx + dy * dy, MIN_SQ_RANGE)
    r = np.sqrt(q)
    return np.stack([np.stack([-dx / r, -dy / r], -1), np.stack([dy / q, -dx / q], -1)], -2)
