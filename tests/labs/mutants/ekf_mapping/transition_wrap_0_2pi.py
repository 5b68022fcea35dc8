"""The heading is wrapped to [0, 2 pi) instead of [-pi, pi).

Angle wrapping far from 0 and near +-pi.

class: angle-wrap
"""

import numpy as np

from robolab.validation import check_finite, check_positive
from solutions.ekf_mapping import _state


def transition_model(state, speed, rotation_speed, dt):
    """Predict the pose with the seed's unicycle model (``transitionModel``).

    The Euler step of the velocity motion model (Probabilistic Robotics,
    section 5.3, without noise), the mean prediction ``g(u_t, mu_{t-1})`` of
    the EKF (Table 3.3, line 2):

    .. math::

        x' = x + v \\cos\\theta \\,\\Delta t, \\qquad
        y' = y + v \\sin\\theta \\,\\Delta t, \\qquad
        \\theta' = \\mathrm{wrap}(\\theta + \\omega \\,\\Delta t)

    The position moves along the *old* heading, as in the seed.

    Parameters
    ----------
    state : array_like, shape (3,) or (N, 3)
        Pose(s) ``(x, y, theta)``; units per cell and radians.
    speed : float
        Forward speed ``v`` (units/s).
    rotation_speed : float
        Turn rate ``omega`` (rad/s).
    dt : float
        Time step (s), > 0.

    Returns
    -------
    numpy.ndarray, same shape as ``state``
        The predicted pose(s), heading wrapped to ``[-pi, pi)``.

    Raises
    ------
    ValueError
        ``state`` is not ``(3,)``/``(N, 3)`` or not finite, a speed is not
        finite, ``dt`` is not > 0.
    """
    s = _state(state, allow_many=True)
    v = check_finite("speed", speed)
    w = check_finite("rotation_speed", rotation_speed)
    dt = check_positive("dt", dt)
    theta = s[..., 2]
    out = np.empty_like(s)
    out[..., 0] = s[..., 0] + v * np.cos(theta) * dt
    out[..., 1] = s[..., 1] + v * np.sin(theta) * dt
    out[..., 2] = np.mod(theta + w * dt, 2 * np.pi)
    return out
