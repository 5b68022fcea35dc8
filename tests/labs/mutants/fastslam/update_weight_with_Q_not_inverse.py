"""The handout's e^T Q e in the weight instead of e^T Q^-1 e.

Numerics of the log form.

class: underflow
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_covariance
from solutions.fastslam import _inv2, _last_dim, _range_bearing, _range_bearing_jacobian


def update_landmark(mean, cov, z, pose, Qt):
    r"""EKF update of one landmark's Gaussian, and the log-likelihood (Table 13.1, lines 12-19).

    .. math::

        \hat z &= h(\mu, x), \quad H = \partial h / \partial \mu, \quad
        Q = H \Sigma H^T + Q_t, \quad K = \Sigma H^T Q^{-1} \\
        e &= z - \hat z \quad (\text{bearing wrapped to } [-\pi, \pi)) \\
        \mu' &= \mu + K e, \qquad \Sigma' = (I - K H)\,\Sigma \\
        \ln w &= -\tfrac12 \ln|2\pi Q| - \tfrac12 e^T Q^{-1} e

    so :math:`w = |2\pi Q|^{-1/2}\exp(-\frac12 e^T Q^{-1} e)`, the Gaussian
    density of the innovation. The seed's handout prints
    :math:`|2\pi Q|^{+1/2}\exp(-\frac12 e^T Q e)` and :math:`e = \hat z - z`:
    both are typos. Without the wrap, a bearing measured as 3.1 rad and predicted
    as -3.1 rad (0.08 rad apart) would look 6.2 rad apart.

    The likelihood is returned as its logarithm: for a landmark estimate metres
    away from the measurement it is :math:`e^{-1000}` or less, which underflows
    to 0 in every particle; the log stays finite and the filter normalizes
    with the log-sum-exp trick.

    Broadcasts over leading dimensions, e.g. ``mean`` (M, 2), ``cov``
    (M, 2, 2), ``pose`` (M, 3) and one ``z`` (2,) for all particles.

    Parameters
    ----------
    mean : array_like, shape (..., 2)
        Landmark mean :math:`\mu`, metres.
    cov : array_like, shape (..., 2, 2)
        Landmark covariance :math:`\Sigma` (symmetric positive definite).
    z : array_like, shape (..., 2)
        Measurement ``[range, bearing]``.
    pose : array_like, shape (..., 3)
        The particle's pose.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance.

    Returns
    -------
    mean : numpy.ndarray, shape (..., 2)
    cov : numpy.ndarray, shape (..., 2, 2)
        Symmetrized.
    log_likelihood : numpy.ndarray, shape (...)
        :math:`\ln \mathcal N(z; \hat z, Q)`, finite.
    """
    mu = _last_dim("mean", mean, 2)
    sigma = as_array("cov", cov, finite=True)
    if sigma.ndim < 2 or sigma.shape[-2:] != (2, 2):
        raise ValueError(f"cov must have shape (..., 2, 2), got {sigma.shape}")
    zz = _last_dim("z", z, 2)
    p = _last_dim("pose", pose, 3)
    qt = check_covariance("Qt", Qt, 2, definite=True)
    zhat = _range_bearing(mu, p)
    H = _range_bearing_jacobian(mu, p)
    Ht = np.swapaxes(H, -1, -2)
    PHt = sigma @ Ht
    S = H @ PHt + qt
    S_inv, det_S = _inv2(S)
    K = PHt @ S_inv
    e = zz - zhat
    e = np.concatenate([e[..., :1], wrap_angle(e[..., 1:2])], -1)
    new_mean = mu + (K @ e[..., None])[..., 0]
    new_cov = sigma - K @ H @ sigma
    new_cov = 0.5 * (new_cov + np.swapaxes(new_cov, -1, -2))
    maha = np.einsum("...i,...ij,...j->...", e, S, e)
    log_like = -0.5 * maha - np.log(2.0 * np.pi) - 0.5 * np.log(det_S)
    return new_mean, new_cov, log_like
