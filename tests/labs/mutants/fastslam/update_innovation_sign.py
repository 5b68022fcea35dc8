"""The handout's innovation e = z_hat - z: the landmark moves away from the measurement.

Sign.

class: formula
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_covariance
from solutions.fastslam import _inv2, _last_dim, _range_bearing, _range_bearing_jacobian


def update_landmark(mean, cov, z, pose, Qt):
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
    S_inv, logdet_S = _inv2(S)
    K = PHt @ S_inv
    e = zhat - zz
    e = np.concatenate([e[..., :1], wrap_angle(e[..., 1:2])], -1)
    new_mean = mu + (K @ e[..., None])[..., 0]
    new_cov = sigma - K @ H @ sigma
    new_cov = 0.5 * (new_cov + np.swapaxes(new_cov, -1, -2))
    maha = np.einsum("...i,...ij,...j->...", e, S_inv, e)
    log_like = -0.5 * maha - np.log(2.0 * np.pi) - 0.5 * logdet_S
    return new_mean, new_cov, log_like
