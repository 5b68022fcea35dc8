"""Visible checks for lab 09, graph-based SLAM with Gauss-Newton.

Quick, friendly and weaker than the hidden tests: shapes, one worked example
and one invariant per exercise.
"""

from __future__ import annotations

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_shape

__all__ = [
    "check_pose_pose_error",
    "check_pose_pose_jacobians",
    "check_pose_landmark_error",
    "check_pose_landmark_jacobians",
    "check_build_linear_system",
    "check_gauss_newton_step",
    "check_optimize_graph",
]


def _numeric_jacobian(f, x, eps=1e-6):
    """Central differences of f at x, column by column (angles in f's output wrapped)."""
    cols = []
    for k in range(len(x)):
        d = np.zeros(len(x))
        d[k] = eps
        diff = np.asarray(f(x + d), float) - np.asarray(f(x - d), float)
        cols.append(diff / (2 * eps))
    return np.stack(cols, -1)


def _line_graph():
    """Three poses 1 m apart on the x axis; a loop edge says pose 2 is only 1.8 m from pose 0."""
    from robolab.datasets import PoseGraph

    return PoseGraph(
        poses=[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        edges=[[0, 1], [1, 2], [0, 2]],
        measurements=[[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.8, 0.0, 0.0]],
        information=np.broadcast_to(np.eye(3), (3, 3, 3)),
    )


@check
def check_pose_pose_error(pose_pose_error) -> None:
    """Pose j exactly where the measurement says: zero error; 0.1 m further along: e_x = 0.1."""
    xi, z = np.array([1.0, 2.0, np.pi / 2]), np.array([1.0, 0.0, 0.0])
    expect_close(
        "error of a measurement that agrees",
        pose_pose_error(xi, [1.0, 3.0, np.pi / 2], z),
        [0.0, 0.0, 0.0],
        atol=1e-12,
    )
    expect_close(
        "pose j 0.1 m further ahead",
        pose_pose_error(xi, [1.0, 3.1, np.pi / 2], z),
        [0.1, 0.0, 0.0],
        atol=1e-12,
    )
    got = expect_shape(
        "errors of 4 edges at once",
        pose_pose_error(np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((4, 3))),
        (4, 3),
    )
    expect_close("errors of 4 edges at once", got, np.zeros((4, 3)))


def _pose_pose_error(xi, xj, z):
    """The check's own t2v(Z^-1 X_i^-1 X_j), for finite differences."""
    from robolab.geometry import relative

    return relative(z, relative(xi, xj))


def _pose_landmark_error(x, lm, z):
    c, s = np.cos(x[2]), np.sin(x[2])
    d = np.asarray(lm, float) - x[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]) - z


def _against_differences(jacobians, error, args, names) -> None:
    """Each returned Jacobian against central differences of ``error`` in argument k."""
    for k, (got, name) in enumerate(zip(jacobians, names, strict=True)):
        expected = _numeric_jacobian(lambda v, k=k: error(*args[:k], v, *args[k + 1 :]), args[k])
        got = expect_shape(name, got, expected.shape)
        if not np.allclose(got, expected, atol=1e-5):
            raise CheckFailed(
                f"{name} differs from finite differences of the error: expected "
                f"{np.array2string(expected, precision=4)}, got {np.array2string(got, precision=4)}"
            )


@check
def check_pose_pose_jacobians(pose_pose_jacobians) -> None:
    """A and B against central finite differences of the error at one edge."""
    xi, xj, z = np.array([1.0, -0.5, 0.7]), np.array([2.5, 1.0, -0.4]), np.array([1.2, 0.9, -1.0])
    _against_differences(
        pose_pose_jacobians(xi, xj, z),
        _pose_pose_error,
        (xi, xj, z),
        ("A = de/dx_i", "B = de/dx_j"),
    )


@check
def check_pose_landmark_error(pose_landmark_error) -> None:
    """Seen from (0, 0, pi/2), the landmark at (0, 2) in the world is 2 m straight ahead."""
    expect_close(
        "landmark exactly where measured",
        pose_landmark_error([0.0, 0.0, np.pi / 2], [0.0, 2.0], [2.0, 0.0]),
        [0.0, 0.0],
        atol=1e-12,
    )
    expect_close(
        "landmark 0.5 m to the left of where measured",
        pose_landmark_error([0.0, 0.0, np.pi / 2], [-0.5, 2.0], [2.0, 0.0]),
        [0.0, 0.5],
        atol=1e-12,
    )
    expect_shape(
        "errors of 5 edges at once",
        pose_landmark_error(np.zeros((5, 3)), np.ones((5, 2)), np.zeros((5, 2))),
        (5, 2),
    )


@check
def check_pose_landmark_jacobians(pose_landmark_jacobians) -> None:
    """A (2 x 3) and B (2 x 2) against central finite differences of the landmark error."""
    x, lm, z = np.array([1.0, -0.5, 0.7]), np.array([-2.0, 3.0]), np.array([1.0, 2.0])
    _against_differences(
        pose_landmark_jacobians(x, lm, z),
        _pose_landmark_error,
        (x, lm, z),
        ("A = de/dx_i", "B = de/dl_k"),
    )


@check
def check_build_linear_system(build_linear_system) -> None:
    """The three-pose line: H is 9 x 9, sparse and symmetric; b is 0 in y and theta."""
    import scipy.sparse

    H, b = build_linear_system(_line_graph())
    if not scipy.sparse.issparse(H):
        raise CheckFailed(f"H must be a scipy.sparse matrix, got {type(H).__name__}")
    dense = expect_shape("H", H.toarray(), (9, 9))
    b = expect_shape("b", b, (9,))
    expect_close("H - H^T", dense - dense.T, np.zeros((9, 9)))
    # x components: the loop edge (1.8 < 2.0) pulls pose 2 back and pose 0 forward
    expect_close("b", b, [-0.2, 0, 0, 0, 0, 0, 0.2, 0, 0], atol=1e-12)


@check
def check_gauss_newton_step(gauss_newton_step) -> None:
    """One step on the three-pose line: pose 0 stays, the x positions solve the linear problem."""
    g = _line_graph()
    new, dx = gauss_newton_step(g)
    poses = expect_shape("new poses", new.poses, (3, 3))
    expect_shape("dx", dx, (9,))
    expect_close("pose 0 (held fixed)", poses[0], [0.0, 0.0, 0.0], atol=1e-12)
    # minimise (x1 - 1)^2 + (x2 - x1 - 1)^2 + (x2 - 1.8)^2: x1 = 2.8 / 3, x2 = 5.6 / 3
    expect_close("x of poses 1 and 2", poses[1:, 0], [2.8 / 3, 5.6 / 3])
    expect_close("the graph passed in", g.poses[:, 0], [0.0, 1.0, 2.0])


@check
def check_optimize_graph(optimize_graph) -> None:
    """The three-pose line converges; its objective never rises; F before the first step is kept."""
    out, history = optimize_graph(_line_graph())
    f = np.asarray(history["objective"], dtype=float)
    if f.ndim != 1 or len(f) < 2:
        raise CheckFailed(f"history['objective'] must hold F before and after each step, got {f}")
    if np.any(np.diff(f) > 1e-9 * f[0]):
        raise CheckFailed(f"the objective rose on this graph: {f}")
    expect_close("final objective", f[-1], 3 * (0.2 / 3) ** 2, rtol=1e-6)
    expect_close("x of the optimized poses", np.asarray(out.poses)[:, 0], [0.0, 2.8 / 3, 5.6 / 3])
