"""G transposed: the heading terms in the last row instead of the last column.

Derivative.

class: formula
"""

import numpy as np

from robolab.validation import check_finite, check_positive
from solutions.ekf_mapping import _state


def state_jacobian(state, speed, rotation_speed, dt):
    """Jacobian ``G_t = dg/dx`` of :func:`transition_model` (the seed's ``stateJacobian``).

    Probabilistic Robotics, Table 3.3 line 3 (``Sigma = G Sigma G^T + R``):

    .. math::

        G = \\begin{pmatrix}
            1 & 0 & -v \\sin\\theta \\,\\Delta t \\\\
            0 & 1 & \\phantom{-}v \\cos\\theta \\,\\Delta t \\\\
            0 & 0 & 1
        \\end{pmatrix}

    ``rotation_speed`` does not enter (the heading update is additive) but is
    kept so that both functions share one signature.

    Parameters
    ----------
    state : array_like, shape (3,)
        Pose ``(x, y, theta)`` at which to linearize.
    speed, rotation_speed, dt : float
        As in :func:`transition_model`.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
    """
    s = _state(state)
    v = check_finite("speed", speed)
    check_finite("rotation_speed", rotation_speed)
    dt = check_positive("dt", dt)
    g = np.eye(3)
    g[2, 0] = -v * np.sin(s[2]) * dt
    g[2, 1] = v * np.cos(s[2]) * dt
    return g
