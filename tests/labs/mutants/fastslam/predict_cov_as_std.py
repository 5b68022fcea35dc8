"""The covariance Q multiplies the standard normals as if it were a standard deviation.

Noise model: variance against standard deviation.

class: formula
"""

from robolab.fiducials import DT
from robolab.validation import as_array, check_covariance, check_positive, check_rng
from solutions.fastslam import _poses, _sample_motion


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
    return _sample_motion(p, u, q, rng, dt)
