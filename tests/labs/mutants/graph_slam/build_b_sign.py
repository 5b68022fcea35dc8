"""b = -J^T Omega e (the right-hand side's sign folded into b).

class: formula
"""

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from solutions.graph_slam import (
    _blocks,
    _check_graph,
    _f,
    pose_landmark_error,
    pose_landmark_jacobians,
    pose_pose_error,
    pose_pose_jacobians,
)


def build_linear_system(graph):
    g = _check_graph(graph)
    n_p3 = 3 * g.n_poses
    n = g.state_size
    parts = []
    if len(g.edges):
        i, j = g.edges[:, 0], g.edges[:, 1]
        xi, xj = g.poses[i], g.poses[j]
        e = pose_pose_error(xi, xj, g.measurements)
        A, B = pose_pose_jacobians(xi, xj, g.measurements)
        parts.append(_blocks(3 * i, 3, 3 * j, 3, _f(A), _f(B), g.information, _f(e)))
    if len(g.landmark_edges):
        i, k = g.landmark_edges[:, 0], g.landmark_edges[:, 1]
        x, lm = g.poses[i], g.landmarks[k]
        e = pose_landmark_error(x, lm, g.landmark_measurements)
        A, B = pose_landmark_jacobians(x, lm, g.landmark_measurements)
        parts.append(
            _blocks(3 * i, 3, n_p3 + 2 * k, 2, _f(A), _f(B), g.landmark_information, _f(e))
        )
    if not parts:
        return scipy.sparse.csr_matrix((n, n)), np.zeros(n)
    rows, cols, vals, bidx, bval = (np.concatenate(p) for p in zip(*parts, strict=True))
    H = scipy.sparse.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()
    b = -np.bincount(bidx, weights=bval, minlength=n)
    return H, b
