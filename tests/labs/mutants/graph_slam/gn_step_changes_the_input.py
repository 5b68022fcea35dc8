"""Adds dx to the graph passed in (in place) and returns that same graph.

class: aliasing
"""

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from robolab.geometry import wrap_angle
from solutions.graph_slam import _check_graph, _f, build_linear_system


def gauss_newton_step(graph):
    g = _check_graph(graph)
    H, b = build_linear_system(g)
    H, b = scipy.sparse.csc_matrix(H), _f(b)  # SuperLU factors CSC
    n = g.state_size
    dx = np.zeros(n)
    if n > 3:
        free = H[3:, 3:]
        try:
            # H is symmetric positive definite once the gauge is fixed: a symmetric
            # ordering and pivots on the diagonal keep the factor sparse (3x faster
            # on the Intel graph than SuperLU's default partial pivoting)
            lu = scipy.sparse.linalg.splu(
                free,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
            dx[3:] = lu.solve(-b[3:])
        except RuntimeError as exc:  # SuperLU: "Factor is exactly singular"
            raise np.linalg.LinAlgError(
                f"H (without the first pose) is singular ({exc}): a vertex that no edge "
                "constrains, or a part of the graph not connected to the first pose"
            ) from None
        if not np.all(np.isfinite(dx)):
            raise np.linalg.LinAlgError("the Gauss-Newton step is not finite: H is singular")
    g.poses[:] += dx[: 3 * g.n_poses].reshape(-1, 3)
    g.poses[:, 2] = wrap_angle(g.poses[:, 2])
    g.landmarks[:] += dx[3 * g.n_poses :].reshape(-1, 2)
    return g, dx
