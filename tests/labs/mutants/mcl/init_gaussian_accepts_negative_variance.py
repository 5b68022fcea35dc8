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
