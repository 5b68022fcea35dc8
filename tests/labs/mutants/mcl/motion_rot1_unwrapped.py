"""Rot1 = atan2(dy, dx) - theta is not wrapped: near +-pi it is off by 2 pi and the noise it scales
explodes.

Angle wrapping far from 0 and near +-pi (odometry deltas).

class: angle-wrap
"""

import math

import numpy as np

from robolab.geometry import angle_diff, wrap_angle
from robolab.validation import as_array, as_poses
from solutions.mcl import IN_PLACE_TRANSLATION, _check_rng


def sample_motion_model_odometry(particles, odom_prev, odom_now, alphas, rng, corrected=False):
    r"""Move every particle by the odometry, with noise: Probabilistic Robotics, Table 5.6.

    The odometry motion from :math:`\bar x = (\bar x, \bar y, \bar\theta)`
    (``odom_prev``) to :math:`\bar x' ` (``odom_now``) is decomposed as

    .. math::

        \delta_{trans} = \sqrt{(\bar x' - \bar x)^2 + (\bar y' - \bar y)^2}, \quad
        \delta_{rot1} = \operatorname{atan2}(\bar y' - \bar y, \bar x' - \bar x) - \bar\theta, \quad
        \delta_{rot2} = \bar\theta' - \bar\theta - \delta_{rot1}

    (seed 004, eq. 11). AMCL's guard: when :math:`\delta_{trans} < 0.01` m
    the bearing of two nearly equal positions is noise, so
    :math:`\delta_{rot1} = 0` (an in-place rotation). Each particle gets its own
    noisy motion,

    .. math::

        \hat\delta_{rot1} &= \delta_{rot1}
            - \varepsilon(\alpha_1 \delta_{rot1}^2 + \alpha_2 \delta_{trans}^2) \\
        \hat\delta_{trans} &= \delta_{trans} - \varepsilon(\alpha_3 \delta_{trans}^2
                               + \alpha_4 \delta_{rot1}^2 + \alpha_4 \delta_{rot2}^2) \\
        \hat\delta_{rot2} &= \delta_{rot2}
            - \varepsilon(\alpha_1 \delta_{rot2}^2 + \alpha_2 \delta_{trans}^2)

    where :math:`\varepsilon(b^2)` is a zero-mean Gaussian of **variance**
    :math:`b^2`. (Seed 004's eq. 12 writes the noise as
    :math:`\varepsilon_{\alpha_1|\delta_{rot2}| + \alpha_2|\delta_{trans}|}`: without
    the squares, i.e. as a standard deviation -- which is what AMCL's plain
    ``ODOM_MODEL_DIFF`` does -- and with :math:`\delta_{rot2}` in the noise of
    :math:`\delta_{rot1}`; Table 5.6 uses variances and :math:`\delta_{rot1}`.)
    Then (eq. 13)

    .. math::

        x' = x + \hat\delta_{trans}\cos(\theta + \hat\delta_{rot1}), \quad
        y' = y + \hat\delta_{trans}\sin(\theta + \hat\delta_{rot1}), \quad
        \theta' = \theta + \hat\delta_{rot1} + \hat\delta_{rot2}.

    With ``corrected=True`` this is AMCL's ``ODOM_MODEL_DIFF_CORRECTED``
    (seed 000, listing 2.1): backward motion (:math:`\delta_{rot1} \approx \pm\pi`)
    is treated like forward motion in the noise, which uses
    :math:`\min(|\delta_{rot}|, |\pi - |\delta_{rot}||)` in place of
    :math:`|\delta_{rot}|` for both rotations (the means are unchanged).

    Parameters
    ----------
    particles : array_like, shape (N, 3)
        Poses before the motion; not modified.
    odom_prev, odom_now : array_like, shape (3,)
        Odometry poses ``(x, y, theta)`` in the odom frame at the previous and
        the current step.
    alphas : array_like, shape (4,)
        :math:`\alpha_1 \dots \alpha_4` (rad^2/rad^2, rad^2/m^2, m^2/m^2, m^2/rad^2), >= 0.
    rng : numpy.random.Generator
        Draws one ``(N, 3)`` block of standard normals.
    corrected : bool
        Use AMCL's diff-corrected noise.

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        New poses, heading wrapped to :math:`[-\pi, \pi)`.

    Raises
    ------
    ValueError
        Bad shapes, non-finite values or a negative alpha.
    TypeError
        ``rng`` is not a Generator or ``corrected`` not a bool.
    """
    p = as_poses("particles", particles)
    if np.ndim(particles) != 2:
        raise ValueError(f"particles must have shape (N, 3), got {np.shape(particles)}")
    a = as_array("alphas", alphas, shape=(4,), finite=True, nonnegative=True)
    _check_rng(rng)
    if not isinstance(corrected, (bool, np.bool_)):
        raise TypeError(f"corrected must be a bool, got {type(corrected).__name__}")
    prev = as_array("odom_prev", odom_prev, shape=(3,), finite=True)
    now = as_array("odom_now", odom_now, shape=(3,), finite=True)
    dx, dy = now[0] - prev[0], now[1] - prev[1]
    trans = math.hypot(dx, dy)
    rot1 = 0.0 if trans < IN_PLACE_TRANSLATION else math.atan2(dy, dx) - prev[2]
    rot2 = angle_diff(angle_diff(now[2], prev[2]), rot1)
    if corrected:
        n1 = min(abs(angle_diff(rot1, 0.0)), abs(angle_diff(rot1, np.pi)))
        n2 = min(abs(angle_diff(rot2, 0.0)), abs(angle_diff(rot2, np.pi)))
    else:
        n1, n2 = rot1, rot2
    var = np.array(
        [
            a[0] * n1**2 + a[1] * trans**2,
            a[2] * trans**2 + a[3] * (n1**2 + n2**2),
            a[0] * n2**2 + a[1] * trans**2,
        ]
    )
    noise = rng.standard_normal((p.shape[0], 3)) * np.sqrt(var)
    r1 = rot1 - noise[:, 0]
    tr = trans - noise[:, 1]
    r2 = rot2 - noise[:, 2]
    heading = p[:, 2] + r1
    return np.column_stack(
        [p[:, 0] + tr * np.cos(heading), p[:, 1] + tr * np.sin(heading), wrap_angle(heading + r2)]
    )
