"""The new headings are not wrapped.

Angle wrapping far from 0 and near +-pi.

class: angle-wrap
"""

import numpy as np

from robolab.fiducials import DT, sqrt_psd
from robolab.validation import as_array, check_covariance, check_positive, check_rng
from solutions.fastslam import _poses


def predict_poses(poses, command, Q, rng, dt=DT):
    r"""Sample every particle's next pose from the lab's motion model (Table 13.1, line 4).

    The fiducial robot's unicycle model with additive Gaussian pose noise
    (the same model :mod:`robolab.fiducials` simulates):

    .. math::

        \begin{pmatrix} x' \\ y' \\ \theta' \end{pmatrix} =
        \begin{pmatrix} x + v\,\Delta t \cos\theta \\ y + v\,\Delta t \sin\theta \\
        \theta + \omega\,\Delta t \end{pmatrix} + w, \qquad w \sim \mathcal N(0, Q),

    independently for each particle, with :math:`\theta'` wrapped to
    :math:`[-\pi, \pi)`.

    Parameters
    ----------
    poses : array_like, shape (M, 3)
        Particle poses; not modified.
    command : array_like, shape (2,)
        ``[v, omega]`` in m/s and rad/s.
    Q : array_like, shape (3, 3)
        Symmetric positive semi-definite noise covariance per step (zeros: no noise).
    rng : numpy.random.Generator
        Source of the noise.
    dt : float
        Time step in seconds.

    Returns
    -------
    numpy.ndarray, shape (M, 3)
        The sampled poses, a new array.
    """
    p = _poses(poses)
    u = as_array("command", command, shape=(2,), finite=True)
    q = check_covariance("Q", Q, 3, definite=False)
    check_rng(rng)
    dt = check_positive("dt", dt)
    noise = rng.standard_normal(p.shape) @ sqrt_psd(q).T
    out = np.empty_like(p)
    out[:, 0] = p[:, 0] + u[0] * dt * np.cos(p[:, 2]) + noise[:, 0]
    out[:, 1] = p[:, 1] + u[0] * dt * np.sin(p[:, 2]) + noise[:, 1]
    out[:, 2] = p[:, 2] + u[1] * dt + noise[:, 2]
    return out
