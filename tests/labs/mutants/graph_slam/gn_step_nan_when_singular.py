"""Solves with spsolve and never checks the result: a pose without edges gives NaN poses.

class: refusal
"""

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from robolab.geometry import wrap_angle

from solutions.graph_slam import _f, _check_graph


def gauss_newton_step(graph):
    g = _check_graph(graph)
    H, b = build_linear_system(g)
    H, b = scipy.sparse.csc_matrix(H), _f(b)  # SuperLU factors CSC
    n = g.state_size
    dx = np.zeros(n)
    if n > 3:
        free = H[3:, 3:]
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            dx[3:] = scipy.sparse.linalg.spsolve(free, -b[3:])
    poses = g.poses + dx[: 3 * g.n_poses].reshape(-1, 3)
    poses[:, 2] = wrap_angle(poses[:, 2])
    landmarks = g.landmarks + dx[3 * g.n_poses :].reshape(-1, 2)
    return g.with_estimate(poses, landmarks), dx
