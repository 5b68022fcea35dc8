r"""Lab 09 reference solution: graph-based SLAM with Gauss-Newton.

Past the handouts: Grisetti, Kuemmerle, Stachniss and Burgard, "A tutorial on
graph-based SLAM" (2010), and Probabilistic Robotics chapter 11 (GraphSLAM,
Tables 11.1-11.5), which builds the same information form :math:`H, b`.

The graph is a :class:`robolab.datasets.PoseGraph`: poses :math:`x_i = (t_i,
\theta_i)` and landmarks :math:`l_k` are vertices; each edge is a measurement with
an information matrix :math:`\Omega`. The estimate minimises

.. math::

    F(x) = \sum_{\langle i,j \rangle} e_{ij}^T \Omega_{ij} e_{ij}
         + \sum_{\langle i,k \rangle} e_{ik}^T \Omega_{ik} e_{ik},

    e_{ij} = \operatorname{t2v}(Z_{ij}^{-1} X_i^{-1} X_j), \qquad
    e_{ik} = R_i^T (l_k - t_i) - z_{ik},

with :math:`X = v2t(x)` the homogeneous 3 x 3 matrix of a pose. The state is the
stacked vector ``[x_0, ..., x_{N-1}, l_0, ..., l_{L-1}]``: pose ``i`` at rows
``3 i .. 3 i + 2``, landmark ``k`` at ``3 N + 2 k .. 3 N + 2 k + 1``.

Every function works on all edges at once: no Python loop over edges or vertices.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from robolab.datasets import PoseGraph
from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_count, check_positive

__all__ = [
    "pose_pose_error",
    "pose_pose_jacobians",
    "pose_landmark_error",
    "pose_landmark_jacobians",
    "build_linear_system",
    "gauss_newton_step",
    "optimize_graph",
]


def _last_dim(name, value, n):
    arr = as_array(name, value, finite=True)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got {arr.shape}")
    return arr


def _pose_pose_parts(xi, xj, z):
    """Broadcast inputs and the pieces the error and its Jacobians share."""
    xi, xj, z = np.broadcast_arrays(
        _last_dim("xi", xi, 3), _last_dim("xj", xj, 3), _last_dim("z", z, 3)
    )
    ci, si = np.cos(xi[..., 2]), np.sin(xi[..., 2])
    dx, dy = xj[..., 0] - xi[..., 0], xj[..., 1] - xi[..., 1]
    # R_i^T (t_j - t_i): pose j's position in the frame of pose i
    local = np.stack([ci * dx + si * dy, -si * dx + ci * dy], -1)
    return xi, xj, z, local


def pose_pose_error(xi, xj, z):
    r"""Error of pose-pose edges, :math:`e_{ij} = \operatorname{t2v}(Z_{ij}^{-1} X_i^{-1} X_j)`.

    Written out, with :math:`R(\cdot)` the 2-D rotation:

    .. math::

        e_{xy} = R_z^T \big(R_i^T (t_j - t_i) - t_z\big), \qquad
        e_\theta = \operatorname{wrap}(\theta_j - \theta_i - \theta_z).

    It is zero when pose j, seen from pose i, is exactly where the measurement
    says. Broadcasts over leading dimensions (all edges at once).

    Parameters
    ----------
    xi, xj : array_like, shape (..., 3)
        Poses ``(x, y, theta)`` of the edge's two ends.
    z : array_like, shape (..., 3)
        Measured pose of j in the frame of i.

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        The error; its angle wrapped to ``[-pi, pi)``.

    Raises
    ------
    ValueError
        ``xi``, ``xj`` or ``z`` not of shape (..., 3), or shapes that do not broadcast.
    """
    xi, xj, z, local = _pose_pose_parts(xi, xj, z)
    u = local - z[..., :2]
    cz, sz = np.cos(z[..., 2]), np.sin(z[..., 2])
    return np.stack(
        [
            cz * u[..., 0] + sz * u[..., 1],
            -sz * u[..., 0] + cz * u[..., 1],
            wrap_angle(xj[..., 2] - xi[..., 2] - z[..., 2]),
        ],
        -1,
    )


def pose_pose_jacobians(xi, xj, z):
    r"""Jacobians :math:`A = \partial e/\partial x_i`, :math:`B = \partial e/\partial x_j`.

    As derived in Grisetti et al.'s tutorial, with :math:`\partial R_i^T / \partial\theta_i`
    the derivative of the transposed rotation:

    .. math::

        A = \begin{pmatrix} -R_z^T R_i^T &
                            R_z^T \frac{\partial R_i^T}{\partial \theta_i} (t_j - t_i) \\
                            0 \;\; 0 & -1 \end{pmatrix}, \qquad
        B = \begin{pmatrix} R_z^T R_i^T & 0 \\ 0 \;\; 0 & 1 \end{pmatrix}.

    Parameters
    ----------
    xi, xj, z : array_like, shape (..., 3)
        As for :func:`pose_pose_error`.

    Returns
    -------
    A, B : numpy.ndarray, shape (..., 3, 3)
        Row r is the gradient of error component r.
    """
    xi, xj, z, local = _pose_pose_parts(xi, xj, z)
    ang = xi[..., 2] + z[..., 2]
    c, s = np.cos(ang), np.sin(ang)  # R_z^T R_i^T = R(-(theta_i + theta_z))
    cz, sz = np.cos(z[..., 2]), np.sin(z[..., 2])
    # dR_i^T/dtheta_i (t_j - t_i) = (local_y, -local_x), rotated by R_z^T
    gx, gy = local[..., 1], -local[..., 0]
    zero, one = np.zeros_like(c), np.ones_like(c)
    B = np.stack(
        [np.stack([c, s, zero], -1), np.stack([-s, c, zero], -1), np.stack([zero, zero, one], -1)],
        -2,
    )
    A = -B
    A[..., 0, 2] = cz * gx + sz * gy
    A[..., 1, 2] = -sz * gx + cz * gy
    return A, B


def pose_landmark_error(x, landmark, z):
    r"""Error of pose-landmark edges, :math:`e_{ik} = R_i^T (l_k - t_i) - z_{ik}`.

    The landmark's position in the frame of pose i, minus where the
    measurement puts it. Broadcasts over leading dimensions.

    Parameters
    ----------
    x : array_like, shape (..., 3)
        Pose(s) ``(x, y, theta)``.
    landmark : array_like, shape (..., 2)
        Landmark position(s).
    z : array_like, shape (..., 2)
        Measured landmark position in the frame of the pose.

    Returns
    -------
    numpy.ndarray, shape (..., 2)
    """
    x, lm, z = _last_dim("x", x, 3), _last_dim("landmark", landmark, 2), _last_dim("z", z, 2)
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    dx, dy = lm[..., 0] - x[..., 0], lm[..., 1] - x[..., 1]
    return np.stack([c * dx + s * dy - z[..., 0], -s * dx + c * dy - z[..., 1]], -1)


def pose_landmark_jacobians(x, landmark, z):
    r"""Jacobians :math:`A = \partial e/\partial x_i` (2 x 3) and :math:`B = \partial e/\partial l`.

    .. math::

        A = \begin{pmatrix} -R_i^T &
                            \frac{\partial R_i^T}{\partial \theta_i} (l_k - t_i) \end{pmatrix},
        \qquad B = R_i^T.

    The measurement ``z`` does not enter (the error is linear in it) but is
    taken for symmetry with :func:`pose_landmark_error` and broadcasting.

    Returns
    -------
    A : numpy.ndarray, shape (..., 2, 3)
    B : numpy.ndarray, shape (..., 2, 2)
    """
    x = _last_dim("x", x, 3)
    lm = _last_dim("landmark", landmark, 2)
    z = _last_dim("z", z, 2)
    shape = np.broadcast_shapes(x.shape[:-1], lm.shape[:-1], z.shape[:-1])
    x, lm = np.broadcast_to(x, shape + (3,)), np.broadcast_to(lm, shape + (2,))
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    dx, dy = lm[..., 0] - x[..., 0], lm[..., 1] - x[..., 1]
    B = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)
    A = np.concatenate([-B, np.stack([-s * dx + c * dy, -c * dx - s * dy], -1)[..., None]], -1)
    return A, B


def _check_graph(graph):
    if not isinstance(graph, PoseGraph):
        raise TypeError(f"graph must be a robolab.datasets.PoseGraph, got {type(graph).__name__}")
    if graph.n_poses < 1:
        raise ValueError("graph must have at least one pose")
    return graph


def _blocks(first, da, second, db, A, B, omega, e):
    """COO triplets of the four H blocks and the b contributions of a set of edges, all at once.

    ``first``/``second`` are each edge's state offsets, ``A`` (E, m, da) and ``B``
    (E, m, db) its Jacobians, ``omega`` (E, m, m), ``e`` (E, m).
    """
    J = np.concatenate([A, B], -1)  # (E, m, da + db)
    OJ = omega @ J
    HJ = np.swapaxes(J, 1, 2) @ OJ  # (E, k, k): J^T Omega J for the edge's two vertices at once
    g = np.einsum("emk,em->ek", OJ, e)  # J^T Omega e
    idx = np.concatenate(
        [first[:, None] + np.arange(da), second[:, None] + np.arange(db)], 1
    )  # (E, k): the edge's state rows
    k = da + db
    rows = np.broadcast_to(idx[:, :, None], (len(idx), k, k))
    cols = np.broadcast_to(idx[:, None, :], (len(idx), k, k))
    return rows.ravel(), cols.ravel(), HJ.ravel(), idx.ravel(), g.ravel()


def build_linear_system(graph):
    r"""The Gauss-Newton system :math:`H \Delta x = -b` of the graph at its current estimate.

    Linearising every error around the estimate, :math:`e(x + \Delta x) \approx e + J \Delta x`,
    gives (Grisetti et al.'s tutorial; Probabilistic Robotics Table 11.2,
    GraphSLAM_linearize, builds the same information form)

    .. math::

        H = \sum J^T \Omega J, \qquad b = \sum J^T \Omega e,

    where each edge's :math:`J` is non-zero only in the blocks of its two
    vertices: the edge adds :math:`A^T\Omega A, A^T\Omega B, B^T\Omega A,
    B^T\Omega B` to the blocks ``(i, i), (i, j), (j, i), (j, j)`` of H and
    :math:`A^T\Omega e, B^T\Omega e` to ``b``. All blocks are assembled at once as
    COO triplets (duplicates summed); no loop over edges.

    Parameters
    ----------
    graph : PoseGraph

    Returns
    -------
    H : scipy.sparse.csr_matrix, shape (n, n)
        ``n = 3 N + 2 L``; symmetric positive semi-definite (the gauge is free).
    b : numpy.ndarray, shape (n,)
    """
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
    b = np.bincount(bidx, weights=bval, minlength=n)
    return H, b


def _f(x):
    return np.asarray(x, dtype=float)


def gauss_newton_step(graph):
    r"""One Gauss-Newton iteration, the first pose held fixed (Probabilistic Robotics Table 11.4).

    Builds :math:`H, b` (:func:`build_linear_system`), removes the first pose's
    three rows and columns (the objective does not change when the whole graph
    moves rigidly, so H is singular until one pose fixes the frame), solves
    :math:`H \Delta x = -b` for the rest with a sparse factorization, and adds
    :math:`\Delta x` to the estimate (headings wrapped to ``[-pi, pi)``).

    Parameters
    ----------
    graph : PoseGraph
        Not modified.

    Returns
    -------
    new_graph : PoseGraph
        The same edges with the updated estimate (new arrays).
    dx : numpy.ndarray, shape (3 N + 2 L,)
        The step; its first three entries are 0.

    Raises
    ------
    numpy.linalg.LinAlgError
        When the reduced H is singular: a vertex no edge constrains, or a part of
        the graph not connected to the first pose.
    """
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
    poses = g.poses + dx[: 3 * g.n_poses].reshape(-1, 3)
    poses[:, 2] = wrap_angle(poses[:, 2])
    landmarks = g.landmarks + dx[3 * g.n_poses :].reshape(-1, 2)
    return g.with_estimate(poses, landmarks), dx


def _objective(graph):
    """F = sum e^T Omega e over both kinds of edges (the lab's own errors)."""
    g = graph
    total = 0.0
    if len(g.edges):
        e = _f(pose_pose_error(g.poses[g.edges[:, 0]], g.poses[g.edges[:, 1]], g.measurements))
        total += float(np.einsum("ei,eij,ej->", e, g.information, e))
    if len(g.landmark_edges):
        e = _f(
            pose_landmark_error(
                g.poses[g.landmark_edges[:, 0]],
                g.landmarks[g.landmark_edges[:, 1]],
                g.landmark_measurements,
            )
        )
        total += float(np.einsum("ei,eij,ej->", e, g.landmark_information, e))
    return total


def optimize_graph(graph, max_iterations=20, tolerance=1e-5):
    r"""Gauss-Newton to convergence, :func:`gauss_newton_step` repeated (Prob. Robotics Table 11.5).

    Repeats :func:`gauss_newton_step` until the objective :math:`F` changes by
    at most ``tolerance`` relative to its previous value,
    :math:`|F_{k-1} - F_k| \le \text{tolerance} \cdot F_{k-1}`, or by at most
    ``tolerance`` itself (F is a sum of squared Mahalanobis distances, without
    unit: this stops a graph whose objective is near 0), or ``max_iterations``
    steps were taken. GTSAM's Gauss-Newton stops the same way (its relative and
    absolute error tolerances, both 1e-5 by default).

    Parameters
    ----------
    graph : PoseGraph
        The initial guess (for example odometry); not modified.
    max_iterations : int
        At least 1.
    tolerance : float
        Relative change of the objective that counts as converged, > 0.

    Returns
    -------
    optimized : PoseGraph
        The graph at the last estimate.
    history : dict
        ``objective`` (k + 1,): :math:`F` before the first step and after each of the
        k steps; ``step`` (k,): :math:`\lVert \Delta x \rVert_\infty` of each step;
        ``converged`` (bool): the last step met the tolerance.
    """
    g = _check_graph(graph)
    iterations = check_count("max_iterations", max_iterations)
    tol = check_positive("tolerance", tolerance)
    objective, steps, converged = [_objective(g)], [], False
    for _ in range(iterations):
        g, dx = gauss_newton_step(g)
        objective.append(_objective(g))
        steps.append(float(np.abs(dx).max(initial=0.0)))
        change = abs(objective[-2] - objective[-1])
        converged = change <= tol * objective[-2] or change <= tol  # relative, or absolute near 0
        if converged:
            break
    history = {"objective": np.array(objective), "step": np.array(steps), "converged": converged}
    return g, history
