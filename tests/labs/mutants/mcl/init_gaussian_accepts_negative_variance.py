"""A covariance with a negative eigenvalue is not refused: its negative part is clipped to 0
silently.

Inputs the notebook says to refuse.

class: refusal
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array
from solutions.mcl import _check_rng, _count


def init_gaussian(pose, cov, n, rng):
    r"""Particles drawn from a Gaussian around a known pose (position tracking).

    .. math::

        x_0^{[m]} \sim \mathcal{N}(\mu, \Sigma), \quad m = 1 \dots n,

    with the heading wrapped to :math:`[-\pi, \pi)` afterwards (AMCL's
    ``initial_pose`` with ``initial_cov_xx``, ``initial_cov_yy``, ``initial_cov_aa``).

    Parameters
    ----------
    pose : array_like, shape (3,)
        Mean ``(x, y, theta)``, metres and radians.
    cov : array_like, shape (3, 3)
        Covariance, symmetric positive semi-definite (m^2, rad^2); zero gives
        ``n`` copies of ``pose``.
    n : int
        Number of particles, >= 1.
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (n, 3)

    Raises
    ------
    ValueError
        Bad shapes, a non-finite value, a covariance that is not symmetric or
        has a negative eigenvalue, or ``n < 1``.
    TypeError
        ``n`` not an integer or ``rng`` not a Generator.
    """
    mu = as_array("pose", pose, shape=(3,), finite=True)
    sigma = as_array("cov", cov, shape=(3, 3), finite=True)
    n = _count("n", n)
    _check_rng(rng)
    scale = max(1.0, float(np.abs(sigma).max()))
    if not np.allclose(sigma, sigma.T, atol=1e-12 * scale, rtol=0):
        raise ValueError("cov must be symmetric")
    evals, evecs = np.linalg.eigh(sigma)
    root = evecs * np.sqrt(np.clip(evals, 0.0, None))  # root @ root.T == cov
    out = mu + rng.standard_normal((n, 3)) @ root.T
    out[:, 2] = wrap_angle(out[:, 2])
    return out
