"""The bearing atan2(dy, dx) - theta is not wrapped.

Angle wrapping far from 0 and near +-pi.

class: angle-wrap
"""

import numpy as np

from solutions.fastslam import _last_dim


def h(landmark, pose):
    r"""Range-bearing measurement :math:`\hat z = h(\mu_j, x)` (Probabilistic Robotics eq. 6.40).

    .. math::

        \hat r = \sqrt{(\mu_x - x)^2 + (\mu_y - y)^2}, \qquad
        \hat\phi = \operatorname{wrap}\big(\operatorname{atan2}(\mu_y - y, \mu_x - x) - \theta\big)

    Broadcasts over leading dimensions (for example ``landmark`` (M, 2) and
    ``pose`` (M, 3) for all particles at once).

    Parameters
    ----------
    landmark : array_like, shape (..., 2)
        Landmark position(s) :math:`\mu_j`, metres.
    pose : array_like, shape (..., 3)
        Robot pose(s) ``(x, y, theta)``.

    Returns
    -------
    numpy.ndarray, shape (..., 2)
        ``[range, bearing]``; bearing wrapped to ``[-pi, pi)``.
    """
    lm, p = _last_dim("landmark", landmark, 2), _last_dim("pose", pose, 3)
    dx = lm[..., 0] - p[..., 0]
    dy = lm[..., 1] - p[..., 1]
    return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx) - p[..., 2]], -1)
