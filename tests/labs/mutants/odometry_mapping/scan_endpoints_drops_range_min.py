"""A reading equal to range_min is dropped (r > range_min instead of r >= range_min).

Boundary values of a validity interval.

class: boundary
"""

import numpy as np

from robolab.geometry import compose, transform_points
from solutions.odometry_mapping import _pose, _scan_arrays


def scan_endpoints(scan, pose, laser_offset):
    r"""World coordinates of the endpoints of a scan's hit beams.

    The laser sits at ``x_s = pose (+) laser_offset`` (pose composition); beam
    ``k`` with range :math:`z_k` at angle :math:`\theta_k` (laser frame) ends at

    .. math::

        \begin{pmatrix} x_k \\ y_k \end{pmatrix} =
        \begin{pmatrix} x_s \\ y_s \end{pmatrix} + z_k
        \begin{pmatrix} \cos(\theta_s + \theta_k) \\ \sin(\theta_s + \theta_k) \end{pmatrix}

    (the endpoint equation of the likelihood field model, Probabilistic
    Robotics Table 6.3, line 4, with the sensor's mounting pose folded into
    :math:`x_s`).

    Only **hit** beams give endpoints: finite ranges with ``r > 0`` and
    ``range_min <= r < range_max``. NaN, 0, inf, ranges below ``range_min`` and
    max-range readings (``r >= range_max``: nothing detected) are left out; they
    are never turned into obstacles.

    Parameters
    ----------
    scan : dict
        ``ranges`` (B,) metres, ``angles`` (B,) radians in the laser frame,
        ``range_min``, ``range_max`` metres.
    pose : array_like, shape (3,)
        Robot (``base_link``) pose ``(x, y, theta)`` in the world.
    laser_offset : array_like, shape (3,)
        Laser pose in ``base_link`` (the ``base_link -> laser`` transform).

    Returns
    -------
    numpy.ndarray, shape (P, 2)
        ``(x, y)`` of each hit beam's endpoint, in the scan's beam order
        (``P`` = number of hit beams, possibly 0).
    """
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser_pose = compose(_pose("pose", pose), _pose("laser_offset", laser_offset))
    with np.errstate(invalid="ignore"):
        hit = np.isfinite(ranges) & (ranges > 0) & (ranges > rmin) & (ranges < rmax)
    r, a = ranges[hit], angles[hit]
    return transform_points(np.stack([r * np.cos(a), r * np.sin(a)], -1), laser_pose)
