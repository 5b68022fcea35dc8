"""The sampled headings are not wrapped to [-pi, pi).

Angle wrapping far from 0 and near +-pi.

class: angle-wrap
"""

import numpy as np

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
    if evals.min() < -1e-12 * scale:
        raise ValueError(f"cov must be positive semi-definite, got eigenvalue {evals.min():.3g}")
    root = evecs * np.sqrt(np.clip(evals, 0.0, None))  # root @ root.T == cov
    out = mu + rng.standard_normal((n, 3)) @ root.T
    return out
