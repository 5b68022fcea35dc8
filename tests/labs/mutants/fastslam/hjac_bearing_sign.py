"""Sign error in the bearing row (dy / q, -dx / q).

Derivative.

class: formula
"""

import numpy as np

from solutions.fastslam import MIN_SQ_RANGE, _last_dim


def h_jacobian(landmark, pose):
    r"""Jacobian :math:`H = \partial h(\mu_j, x) / \partial \mu_j` with respect to the landmark.

    With :math:`\delta = \mu_j - (x, y)^T` and :math:`q = \delta^T\delta`
    (Probabilistic Robotics eq. 13.11 restricted to the landmark; the seed's
    hints give the bearing row):

    .. math::

        H = \begin{pmatrix} \delta_x / \sqrt q & \delta_y / \sqrt q \\
                            -\delta_y / q & \delta_x / q \end{pmatrix}

    :math:`q` is floored at :data:`MIN_SQ_RANGE` so that a landmark estimate
    on top of the robot gives a large but finite Jacobian.

    Parameters
    ----------
    landmark : array_like, shape (..., 2)
    pose : array_like, shape (..., 3)

    Returns
    -------
    numpy.ndarray, shape (..., 2, 2)
        Row 0 is the range's gradient, row 1 the bearing's.
    """
    lm, p = _last_dim("landmark", landmark, 2), _last_dim("pose", pose, 3)
    dx = lm[..., 0] - p[..., 0]
    dy = lm[..., 1] - p[..., 1]
    q = np.maximum(dx * dx + dy * dy, MIN_SQ_RANGE)
    r = np.sqrt(q)
    return np.stack([np.stack([dx / r, dy / r], -1), np.stack([dy / q, -dx / q], -1)], -2)
