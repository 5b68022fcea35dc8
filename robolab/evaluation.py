r"""Evaluation helpers shared by labs and tests: SE(2) alignment, trajectory and map errors.

Alignment
    :func:`align_points` finds the rigid motion (rotation and translation, no scale)
    that best maps one 2-D point set onto another in the least-squares sense, in
    closed form (Umeyama 1991 / Horn 1987 restricted to the plane):

    .. math::

        (R^*, t^*) = \arg\min_{R \in SO(2),\, t} \sum_i w_i \lVert R p_i + t - q_i \rVert^2 ,
        \quad H = \sum_i w_i (p_i - \bar p)(q_i - \bar q)^T = U S V^T ,
        \quad R^* = V \operatorname{diag}(1, \det V U^T) U^T ,
        \quad t^* = \bar q - R^* \bar p .

    SLAM estimates a map and path only up to such a motion (the first pose fixes the
    frame), so errors are measured after it. :func:`align_path` applies it to poses.
Trajectory errors
    :func:`absolute_trajectory_error` (ATE: position errors after alignment) and
    :func:`relative_pose_error` (RPE: the error of the motion over ``delta`` steps,
    which drift cannot hide), as Sturm et al. 2012 define them.
Map comparison
    :func:`occupied_distances` (how far each occupied cell of a map lies from the
    nearest occupied cell of a reference) and :func:`occupancy_iou` (intersection over
    union of the occupied cells, with a distance tolerance).
Graph objective
    :func:`graph_objective`: the weighted sum of squared edge errors of a
    :class:`robolab.datasets.PoseGraph` that graph-based SLAM minimises (lab 09's
    grader and its benchmark judge a solver by it).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from robolab.datasets.g2o import PoseGraph
from robolab.geometry import angle_diff, compose, relative, transform_points
from robolab.maps import OccupancyGrid
from robolab.validation import as_array, check_count, check_positive

__all__ = [
    "align_points",
    "align_path",
    "absolute_trajectory_error",
    "relative_pose_error",
    "occupied_distances",
    "occupancy_iou",
    "graph_objective",
]


def _points(name: str, value) -> np.ndarray:
    p = as_array(name, value, ndim=2)
    if p.shape[1] != 2:
        raise ValueError(f"{name} must have shape (N, 2), got {p.shape}")
    return p


def align_points(source, target, weights=None) -> np.ndarray:
    """The SE(2) pose ``T`` that best maps ``source`` onto ``target`` (module docstring).

    Parameters
    ----------
    source, target : array_like, shape (N, 2)
        Corresponding points. Rows where either is NaN (e.g. landmarks never
        observed) are left out.
    weights : array_like, shape (N,), optional
        Non-negative weights (default equal).

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``(x, y, theta)``: ``transform_points(source, T)`` is the aligned source.

    Raises
    ------
    ValueError
        Mismatched shapes, infinite values, fewer than two usable points, or points
        that all coincide (the rotation is then undetermined).
    """
    p, q = _points("source", source), _points("target", target)
    if p.shape != q.shape:
        raise ValueError(f"source and target must have the same shape, got {p.shape}, {q.shape}")
    if np.isinf(p).any() or np.isinf(q).any():
        raise ValueError("source and target must not contain inf")
    w = (
        np.ones(len(p))
        if weights is None
        else as_array("weights", weights, shape=(len(p),), finite=True, nonnegative=True)
    )
    use = ~(np.isnan(p).any(axis=1) | np.isnan(q).any(axis=1)) & (w > 0)
    if use.sum() < 2:
        raise ValueError(f"need at least two corresponding points, got {int(use.sum())}")
    p, q, w = p[use], q[use], w[use] / w[use].sum()
    pm, qm = w @ p, w @ q
    h = (p - pm).T @ (w[:, None] * (q - qm))
    if not np.abs(h).max() > 0:
        raise ValueError("the source points all coincide: the rotation is undetermined")
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    r = vt.T @ np.diag([1.0, d]) @ u.T
    t = qm - r @ pm
    return np.array([t[0], t[1], np.arctan2(r[1, 0], r[0, 0])])


def _poses(name: str, value) -> np.ndarray:
    p = as_array(name, value, ndim=2, finite=True)
    if p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError(f"{name} must have shape (T, 3) with T >= 1, got {p.shape}")
    return p


def align_path(estimate, truth) -> tuple[np.ndarray, np.ndarray]:
    """Align an estimated path to the true one by the SE(2) motion of their positions.

    Returns
    -------
    aligned : numpy.ndarray, shape (T, 3)
        ``compose(T, estimate)``: positions moved and headings rotated.
    transform : numpy.ndarray, shape (3,)
    """
    est, tru = _poses("estimate", estimate), _poses("truth", truth)
    if est.shape != tru.shape:
        raise ValueError(
            f"estimate and truth must have the same shape, got {est.shape}, {tru.shape}"
        )
    pose = align_points(est[:, :2], tru[:, :2])
    return compose(pose, est), pose


def absolute_trajectory_error(estimate, truth, *, align: bool = True) -> dict:
    """ATE: the position error of every pose, after SE(2) alignment (unless ``align=False``).

    Returns
    -------
    dict
        ``errors`` (T,) metres, ``rmse``, ``mean``, ``median``, ``max``; ``heading_errors``
        (T,) radians (absolute, wrapped); ``transform`` (3,) the alignment used.
    """
    est, tru = _poses("estimate", estimate), _poses("truth", truth)
    if est.shape != tru.shape:
        raise ValueError(
            f"estimate and truth must have the same shape, got {est.shape}, {tru.shape}"
        )
    transform = np.zeros(3)
    if align:
        est, transform = align_path(est, tru)
    e = np.hypot(*(est[:, :2] - tru[:, :2]).T)
    return {
        "errors": e,
        "rmse": float(np.sqrt(np.mean(e**2))),
        "mean": float(e.mean()),
        "median": float(np.median(e)),
        "max": float(e.max()),
        "heading_errors": np.abs(angle_diff(est[:, 2], tru[:, 2])),
        "transform": transform,
    }


def relative_pose_error(estimate, truth, delta: int = 1) -> dict:
    """RPE: the error of the relative motion between poses ``delta`` steps apart.

    For each ``i``, :math:`E_i = (q_i^{-1} q_{i+\\Delta})^{-1} (p_i^{-1} p_{i+\\Delta})`
    with ``p`` the estimate and ``q`` the truth; it does not depend on the frames of
    either path, so no alignment is needed.

    Returns
    -------
    dict
        ``translation`` (T - delta,) metres and ``rotation`` (T - delta,) radians
        (absolute); ``translation_rmse``, ``rotation_rmse``.
    """
    est, tru = _poses("estimate", estimate), _poses("truth", truth)
    if est.shape != tru.shape:
        raise ValueError(
            f"estimate and truth must have the same shape, got {est.shape}, {tru.shape}"
        )
    d = check_count("delta", delta)
    if d >= len(est):
        raise ValueError(f"delta must be < the number of poses ({len(est)}), got {d}")
    err = relative(relative(tru[:-d], tru[d:]), relative(est[:-d], est[d:]))
    trans, rot = np.hypot(err[:, 0], err[:, 1]), np.abs(err[:, 2])
    return {
        "translation": trans,
        "rotation": rot,
        "translation_rmse": float(np.sqrt(np.mean(trans**2))),
        "rotation_rmse": float(np.sqrt(np.mean(rot**2))),
    }


def _occupied_points(name: str, grid, transform) -> np.ndarray:
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"{name} must be an OccupancyGrid, got {type(grid).__name__}")
    pts = grid.cell_to_world(np.argwhere(grid.occupied))
    if transform is not None:
        pts = transform_points(pts, as_array("transform", transform, shape=(3,), finite=True))
    return pts


def occupied_distances(grid: OccupancyGrid, reference: OccupancyGrid, transform=None) -> np.ndarray:
    """Distance (metres) from each occupied cell centre of ``grid`` to the nearest of ``reference``.

    The maps may differ in resolution, size and origin; ``transform`` (3,) first moves
    ``grid``'s cells (e.g. an alignment). Unknown cells of either map play no part.
    A perfect map gives zeros; half a cell is the rounding floor between grids that
    do not share cell centres.

    Raises
    ------
    ValueError
        ``reference`` has no occupied cell.
    """
    ref = _occupied_points("reference", reference, None)
    if len(ref) == 0:
        raise ValueError("reference has no occupied cell to measure distances to")
    pts = _occupied_points("grid", grid, transform)
    if len(pts) == 0:
        return np.empty(0)
    return cKDTree(ref).query(pts)[0]


def occupancy_iou(
    grid: OccupancyGrid, reference: OccupancyGrid, tolerance: float = 0.0, transform=None
) -> float:
    r"""Intersection over union of the occupied cells, matching within ``tolerance`` metres.

    With :math:`A` and :math:`B` the occupied cell centres of ``grid`` and
    ``reference``, a cell matches when a cell of the other map lies within the
    tolerance (plus a hair for rounding);

    .. math:: \mathrm{IoU} = \frac{I}{|A| + |B| - I}, \qquad
              I = \tfrac12 \big(|\{a : d(a, B) \le \tau\}| + |\{b : d(b, A) \le \tau\}|\big)

    so that with ``tolerance = 0`` on two maps of the same geometry it is the plain
    IoU :math:`|A \cap B| / |A \cup B|`. 1 means the same walls, 0 none in common.
    Two maps without occupied cells have IoU 1.
    """
    tol = check_positive("tolerance", tolerance, allow_zero=True)
    a = _occupied_points("grid", grid, transform)
    b = _occupied_points("reference", reference, None)
    if len(a) == 0 and len(b) == 0:
        return 1.0
    if len(a) == 0 or len(b) == 0:
        return 0.0
    eps = 1e-9 * max(grid.resolution, reference.resolution)
    hit_a = np.count_nonzero(cKDTree(b).query(a)[0] <= tol + eps)
    hit_b = np.count_nonzero(cKDTree(a).query(b)[0] <= tol + eps)
    inter = 0.5 * (hit_a + hit_b)
    return float(inter / (len(a) + len(b) - inter))


def _pose_pose_errors(graph: PoseGraph) -> np.ndarray:
    """``t2v(Z_ij^-1 X_i^-1 X_j)`` of every pose-pose edge, (E, 3)."""
    xi, xj, z = graph.poses[graph.edges[:, 0]], graph.poses[graph.edges[:, 1]], graph.measurements
    return relative(z, relative(xi, xj))


def _pose_landmark_errors(graph: PoseGraph) -> np.ndarray:
    """``R_i^T (l_k - t_i) - z_ik`` of every pose-landmark edge, (F, 2)."""
    x = graph.poses[graph.landmark_edges[:, 0]]
    d = graph.landmarks[graph.landmark_edges[:, 1]] - x[:, :2]
    c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
    local = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], -1)
    return local - graph.landmark_measurements


def graph_objective(graph: PoseGraph) -> float:
    r"""The graph-SLAM objective :math:`F = \sum e^T \Omega e` over all edges of ``graph``.

    Pose-pose edges (Grisetti et al., "A tutorial on graph-based SLAM", 2010):
    :math:`e_{ij} = \operatorname{t2v}(Z_{ij}^{-1} X_i^{-1} X_j)`, its angle wrapped
    to :math:`[-\pi, \pi)`; pose-landmark edges: :math:`e_{ik} = R_i^T (l_k - t_i) - z_{ik}`.
    Probabilistic Robotics chapter 11 writes the same sum as
    GraphSLAM's negative log posterior, up to a factor 1/2 and a constant.

    Parameters
    ----------
    graph : PoseGraph

    Returns
    -------
    float
        Non-negative (the information matrices are positive semi-definite);
        unchanged when the whole graph moves rigidly.
    """
    if not isinstance(graph, PoseGraph):
        raise TypeError(f"graph must be a robolab.datasets.PoseGraph, got {type(graph).__name__}")
    e = _pose_pose_errors(graph)
    total = np.einsum("ei,eij,ej->", e, graph.information, e)
    f = _pose_landmark_errors(graph)
    return float(total + np.einsum("ei,eij,ej->", f, graph.landmark_information, f))
