"""Writes the new landmark's own block and its correlation with the pose, but keeps what its
rows held with the other landmarks.

class: self-consistency
"""

import numpy as np

from robolab.validation import as_array, check_covariance
from solutions.ekf_slam import _belief, _landmark_ids


def add_landmark(mu, sigma, z, j, Qt):
    m, s = _belief(mu, sigma)
    jj = int(_landmark_ids("j", j, (m.size - 3) // 2, scalar=True))
    zz = as_array("z", z, shape=(2,), finite=True)
    if zz[0] < 0:
        raise ValueError(f"z's range must be >= 0, got {zz[0]}")
    qt = check_covariance("Qt", Qt, 2)
    r, angle = zz[0], m[2] + zz[1]
    c, sn = np.cos(angle), np.sin(angle)
    gx = np.array([[1.0, 0.0, -r * sn], [0.0, 1.0, r * c]])
    gz = np.array([[c, -r * sn], [sn, r * c]])
    cols = slice(3 + 2 * jj, 5 + 2 * jj)
    new_mu = m.copy()
    new_mu[cols] = m[0] + r * c, m[1] + r * sn
    new_sigma = s.copy()
    new_sigma[cols, :3] = gx @ s[:3, :3]
    new_sigma[:3, cols] = new_sigma[cols, :3].T
    new_sigma[cols, cols] = gx @ s[:3, :3] @ gx.T + gz @ qt @ gz.T
    return new_mu, new_sigma
