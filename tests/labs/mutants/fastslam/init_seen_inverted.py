"""Seen is True for first_observation and False for prior (the two modes swapped).

Empty or partially known maps.

class: empty-map
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_count
from solutions.fastslam import INIT_MODES, SIGMA0


def init_particles(n_particles, n_landmarks, x0, init="prior"):
    r"""Create the initial FastSLAM particle set (seed 003, "Data Structure Initialization").

    Every particle starts at the known pose :math:`x_0` (SLAM fixes the map's
    frame by the start pose) with equal weight :math:`1/M`.

    ``init="prior"`` (the seed): every landmark has the vague Gaussian belief
    :math:`\mu_0 = 0`, :math:`\Sigma_0 = 10^4 I`, so ``seen`` is all True and the
    first observation is an ordinary EKF update from that prior.

    ``init="first_observation"`` (the book, Table 13.1 lines 7-10): no landmark
    has a belief yet (``seen`` all False; ``means`` and ``covs`` hold the
    placeholders 0 and :math:`10^4 I`); the first observation of landmark j
    initializes it by inverting the measurement model,
    :math:`\mu = h^{-1}(z, x)`, :math:`\Sigma = H^{-1} Q_t H^{-T}`.

    Parameters
    ----------
    n_particles : int
        Number of particles M >= 1.
    n_landmarks : int
        Number of landmarks K >= 1.
    x0 : array_like, shape (3,)
        Start pose ``(x, y, theta)``.
    init : {"prior", "first_observation"}
        How landmarks start (see above).

    Returns
    -------
    dict of numpy arrays
        ``poses`` (M, 3), ``means`` (M, K, 2), ``covs`` (M, K, 2, 2),
        ``seen`` (M, K) bool, ``weights`` (M,); every array is its own copy.
    """
    m = check_count("n_particles", n_particles)
    k = check_count("n_landmarks", n_landmarks)
    pose = as_array("x0", x0, shape=(3,), finite=True).copy()
    pose[2] = wrap_angle(pose[2])
    if init not in INIT_MODES:
        raise ValueError(f"init must be one of {INIT_MODES}, got {init!r}")
    return {
        "poses": np.tile(pose, (m, 1)),
        "means": np.zeros((m, k, 2)),
        "covs": np.broadcast_to(SIGMA0 * np.eye(2), (m, k, 2, 2)).copy(),
        "seen": np.full((m, k), init == "first_observation"),
        "weights": np.full(m, 1.0 / m),
    }
