# ---
# jupyter:
#   jupytext:
#     cell_metadata_filter: tags
#     notebook_metadata_filter: kernelspec,language_info,robolab
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
#   language_info:
#     name: python
#   robolab:
#     lab: graph_slam
# ---

# %% [markdown]
# # Lab 09 — Graph-based SLAM with Gauss-Newton
#
# *References: Probabilistic Robotics (Thrun, Burgard, Fox), Chapter 11 (**GraphSLAM**, Tables 11.1–11.5); G. Grisetti, R. Kümmerle, C. Stachniss, W. Burgard, "A tutorial on graph-based SLAM", IEEE ITS Magazine, 2010.*
#
# EKF-SLAM and FastSLAM are *filters*: they fold each measurement into the current belief and move on. Graph-based SLAM keeps every measurement. Each robot pose $x_i = (t_i, \theta_i)$ and each landmark $l_k$ is a **vertex** of a graph; each measurement is an **edge** between two vertices with an information matrix $\Omega$ (the inverse of its covariance). The best estimate is the one that disagrees least with all measurements at once:
#
# $$
# x^* = \arg\min_x F(x), \qquad F(x) = \sum_{\langle i,j\rangle} e_{ij}^T\, \Omega_{ij}\, e_{ij} + \sum_{\langle i,k\rangle} e_{ik}^T\, \Omega_{ik}\, e_{ik} .
# $$
#
# With Gaussian noise this is the maximum of the posterior over the whole path and map (Probabilistic Robotics, chapter 11, writes $F/2$ as GraphSLAM's negative log posterior, up to a constant). You will write, in order: the errors and Jacobians of the two kinds of edges, the sparse linear system of one Gauss-Newton iteration, the iteration itself, and the loop that runs it to convergence. After each exercise a check cell runs a quick test.
#
# Units: metres, radians. Angles are wrapped to $[-\pi, \pi)$ with `robolab.geometry.wrap_angle`. The objective $F$ is a sum of squared Mahalanobis distances and has no unit.

# %%
import time

import matplotlib.pyplot as plt
import numpy as np

from robolab.checks import graph_slam as checks
from robolab.datasets import PoseGraph, locate, read_g2o
from robolab.evaluation import graph_objective
from robolab.geometry import wrap_angle
from robolab.plotting import new_axes
from robolab.plotting.core import panel_grid
from robolab.plotting.graph_slam import plot_objective_history, plot_pose_graph, plot_sparsity

# %% [markdown]
# ## 1. The graphs
#
# Graphs come in the **g2o** text format, one element a line:
#
# ```
# VERTEX_SE2  id x y theta                          a pose and its initial guess
# VERTEX_XY   id x y                                a landmark and its initial guess
# EDGE_SE2    i j dx dy dtheta I11 I12 I13 I22 I23 I33   pose j measured from pose i
# EDGE_SE2_XY i j dx dy I11 I12 I22                 landmark j measured from pose i
# ```
#
# The information matrix is written as its upper triangle. `read_g2o` returns a `PoseGraph` of arrays: `poses` (N, 3), `landmarks` (L, 2), `edges` (E, 2) row indices with `measurements` (E, 3) and `information` (E, 3, 3), and `landmark_edges` (F, 2) with `landmark_measurements` (F, 2) and `landmark_information` (F, 2, 2). Vertex ids in the file need not be 0..N-1: rows are the vertices sorted by id, and `pose_ids` keeps the ids.
#
# The state is one long vector $x = (x_0, \dots, x_{N-1}, l_0, \dots, l_{L-1})$ of length $3N + 2L$: pose $i$ at entries $3i \dots 3i+2$, landmark $k$ at $3N + 2k$, $3N + 2k + 1$.
#
# We learn on a simulated graph that comes with robolab: a robot drives three laps around a 12 m × 8 m block through a field of landmarks. Odometry edges join consecutive poses, loop-closure edges join poses of different laps that are close (as a scan matcher would find them), and pose-landmark edges hold each landmark's measured position in the robot's frame. The initial guess integrates the noisy odometry, so it drifts; the simulator's truth is stored beside it.

# %%
from robolab import DATA_DIR
from robolab.evaluation import absolute_trajectory_error

graph = read_g2o(DATA_DIR / "graph_slam.g2o")
truth = np.load(DATA_DIR / "graph_slam_truth.npz")
print(f"{graph.n_poses} poses, {graph.n_landmarks} landmarks, {len(graph.edges)} pose-pose edges, "
      f"{len(graph.landmark_edges)} pose-landmark edges; state of {graph.state_size} numbers")
print(f"F of the initial guess: {graph_objective(graph):.4g}; "
      f"position error against the truth (RMSE after alignment): {absolute_trajectory_error(graph.poses, truth['poses'])['rmse']:.2f} m")

ax = new_axes("The bundled graph: initial guess (odometry) and truth [m]", figsize=(8, 6))
ax.plot(*truth["poses"][:, :2].T, "-", color="black", linewidth=1.0, label="true path")
ax.scatter(*truth["landmarks"].T, marker="+", s=40, color="black", label="true landmarks")
plot_pose_graph(graph, ax, color="tab:blue", label="initial guess", legend=False)
ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1), fontsize="small")
plt.show()

# %% [markdown]
# `graph_objective(graph)` evaluates $F$ with the errors defined below. It is the grader's yardstick, and you may call it (to print or plot the objective); the exercises ask you to compute the errors, Jacobians and steps yourself.

# %% [markdown]
# ## 2. The error of a pose-pose edge
#
# Write a pose as the homogeneous matrix $X_i = \begin{pmatrix} R_i & t_i \\ 0 & 1\end{pmatrix}$ and the measurement $z_{ij}$ as $Z_{ij}$: pose $j$ as seen from pose $i$. Then $X_i^{-1} X_j$ is where pose $j$ *is*, seen from pose $i$, and the error compares it with where the measurement *says* it is:
#
# $$
# e_{ij} = \operatorname{t2v}\big(Z_{ij}^{-1}\, X_i^{-1}\, X_j\big)
# = \begin{pmatrix} R_z^T\big(R_i^T (t_j - t_i) - t_z\big) \\ \operatorname{wrap}(\theta_j - \theta_i - \theta_z) \end{pmatrix}.
# $$
#
# `t2v` turns a homogeneous matrix back into $(x, y, \theta)$. The error is zero exactly when $x_j = x_i \oplus z_{ij}$. Write it for **all edges at once**: inputs of shape (E, 3), output (E, 3); a single edge of shape (3,) must work too. No Python loop over edges.

# %% tags=["exercise"]
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_pose_pose_error(pose_pose_error)

# %% [markdown]
# ## 3. Its Jacobians
#
# Gauss-Newton linearises every error around the current estimate: $e_{ij}(x + \Delta x) \approx e_{ij} + A_{ij}\,\Delta x_i + B_{ij}\,\Delta x_j$ with $A_{ij} = \partial e_{ij} / \partial x_i$ and $B_{ij} = \partial e_{ij} / \partial x_j$ (each 3 × 3):
#
# $$
# A_{ij} = \begin{pmatrix} -R_z^T R_i^T & R_z^T \dfrac{\partial R_i^T}{\partial \theta_i}(t_j - t_i) \\ 0 \quad 0 & -1 \end{pmatrix}, \qquad
# B_{ij} = \begin{pmatrix} R_z^T R_i^T & 0 \\ 0 \quad 0 & 1 \end{pmatrix}, \qquad
# \frac{\partial R_i^T}{\partial \theta_i} = \begin{pmatrix} -\sin\theta_i & \cos\theta_i \\ -\cos\theta_i & -\sin\theta_i \end{pmatrix}.
# $$
#
# Return `A` and `B` of shape (E, 3, 3) for E edges, (3, 3) for one.

# %% tags=["exercise"]
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_pose_pose_jacobians(pose_pose_jacobians)

# %% [markdown]
# A Jacobian is easy to get wrong by a sign or a transposition: compare yours with central finite differences $\big(e(x + \varepsilon u_k) - e(x - \varepsilon u_k)\big)/2\varepsilon$, column by column.

# %%
xi, xj, z = np.array([1.0, -0.5, 0.7]), np.array([2.5, 1.0, -0.4]), np.array([1.2, 0.9, -1.0])
eps = 1e-6
A, B = pose_pose_jacobians(xi, xj, z)
A_fd = np.column_stack([(pose_pose_error(xi + eps * u, xj, z) - pose_pose_error(xi - eps * u, xj, z)) / (2 * eps) for u in np.eye(3)])
B_fd = np.column_stack([(pose_pose_error(xi, xj + eps * u, z) - pose_pose_error(xi, xj - eps * u, z)) / (2 * eps) for u in np.eye(3)])
print("A:\n", np.round(A, 6))
print(f"largest difference from finite differences: A {np.abs(A - A_fd).max():.1e}, B {np.abs(B - B_fd).max():.1e}")

# %% [markdown]
# ## 4. The error of a pose-landmark edge, and its Jacobians
#
# A pose-landmark edge measures the landmark's position in the robot's frame (for example from a range and a bearing, turned into $x, y$). Its error is
#
# $$
# e_{ik} = R_i^T (l_k - t_i) - z_{ik}, \qquad
# A_{ik} = \frac{\partial e_{ik}}{\partial x_i} = \begin{pmatrix} -R_i^T & \dfrac{\partial R_i^T}{\partial \theta_i}(l_k - t_i) \end{pmatrix} \;(2 \times 3), \qquad
# B_{ik} = \frac{\partial e_{ik}}{\partial l_k} = R_i^T \;(2 \times 2).
# $$

# %% tags=["exercise"]
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_pose_landmark_error(pose_landmark_error)


# %% tags=["exercise"]
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_pose_landmark_jacobians(pose_landmark_jacobians)

# %% [markdown]
# ## 5. The linear system $H\,\Delta x = -b$
#
# Substituting the linearised errors into $F$ gives a quadratic in $\Delta x$ whose minimum solves $H \Delta x = -b$ with
#
# $$
# H = \sum_{\text{edges}} J^T \Omega J, \qquad b = \sum_{\text{edges}} J^T \Omega\, e .
# $$
#
# Each edge's $J$ is zero except in the columns of its two vertices, so an edge touches only four blocks of $H$ and two of $b$:
#
# $$
# H_{ii} \mathrel{+}= A^T\Omega A, \quad H_{ij} \mathrel{+}= A^T\Omega B, \quad H_{ji} \mathrel{+}= B^T\Omega A, \quad H_{jj} \mathrel{+}= B^T\Omega B, \qquad b_i \mathrel{+}= A^T \Omega e, \quad b_j \mathrel{+}= B^T\Omega e .
# $$
#
# $H$ is therefore **sparse**: a 3 × 3 block per pose and per edge, out of $(3N)^2$ entries. Build it with `scipy.sparse` **without a Python loop over edges**: compute every edge's blocks at once (batched matrix products, `@` on (E, 3, 3) stacks), make arrays of their row indices, column indices and values, and hand them all to `scipy.sparse.coo_matrix((values, (rows, cols)), shape=(n, n))`, which **adds up** entries that share a position (as two edges of the same pose must). Return `H.tocsr()`. The same trick with `np.bincount(index, weights=values, minlength=n)` builds $b$.

# %% tags=["exercise"]
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_build_linear_system(build_linear_system)

# %% [markdown]
# The non-zero pattern of $H$ for the bundled graph (the red lines separate the poses from the landmarks), and for the same graph without its landmarks. Off the diagonal, a block $(i, j)$ is non-zero only if an edge joins $i$ and $j$: the odometry chain makes the band along the diagonal, loop closures the entries away from it, landmarks the blocks in the last rows and columns.

# %%
poses_only = PoseGraph(graph.poses, graph.edges, graph.measurements, graph.information)
H, b = build_linear_system(graph)
H_poses, _ = build_linear_system(poses_only)
fig, axes = panel_grid(2, panel=(5.5, 5.0), max_cols=2, title="Sparsity pattern of H (black: non-zero entry)")
plot_sparsity(H, axes[0], title=f"poses and landmarks, {H.shape[0]} x {H.shape[0]}", n_poses=graph.n_poses)
plot_sparsity(H_poses, axes[1], title=f"poses only, {H_poses.shape[0]} x {H_poses.shape[0]}")
for ax in axes:
    ax.set_xlabel("column (state index)"); ax.set_ylabel("row (state index)")
plt.show()
for name, M in (("poses and landmarks", H), ("poses only", H_poses)):
    print(f"{name}: H has {M.nnz} stored entries of {M.shape[0] ** 2} ({100 * M.nnz / M.shape[0] ** 2:.2f} %)")

# %% [markdown]
# ## 6. One Gauss-Newton step, with the first pose fixed
#
# $F$ does not change when the whole graph is moved rigidly: every error is measured *between* vertices. So $H$ is singular (three directions, a global translation and rotation, cost nothing) and $H\Delta x = -b$ has no unique solution. Fix the **first pose**: remove its three rows and columns, solve the rest, and set its $\Delta x$ to zero.

# %%
eigenvalues = np.linalg.eigvalsh(H.toarray())
print("the five smallest eigenvalues of H:", np.array2string(eigenvalues[:5], precision=3))
print("largest eigenvalue:", f"{eigenvalues[-1]:.3g}")
print("smallest eigenvalue without the first pose's rows and columns:",
      f"{np.linalg.eigvalsh(H.toarray()[3:, 3:])[0]:.3g}")

# %% [markdown]
# Solve the reduced system with a sparse factorization (`scipy.sparse.linalg.spsolve`, or `splu(...).solve`, on a CSC matrix), never with a dense inverse: for the Intel graph of section 8, $H$ is 5184 × 5184. Add $\Delta x$ to the poses and landmarks, wrap the headings, and return a new `PoseGraph` (`graph.with_estimate(poses, landmarks)` makes one) and $\Delta x$. If a vertex has no edge, $H$ stays singular: raise `numpy.linalg.LinAlgError` rather than return NaN poses.

# %% tags=["exercise"]
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_gauss_newton_step(gauss_newton_step)

# %% [markdown]
# ## 7. Iterating to convergence
#
# One step is exact only for a linear problem; the rotations make ours non-linear, so iterate: build, solve, update, until the objective stops changing. Record $F$ before the first step and after every step.

# %% tags=["exercise"]
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
    # YOUR CODE HERE
    raise NotImplementedError


# %%
checks.check_optimize_graph(optimize_graph)

# %% [markdown]
# ### The bundled graph, optimized

# %%
start = time.process_time()
optimized, history = optimize_graph(graph)
seconds = time.process_time() - start
f = history["objective"]
print(f"F {f[0]:.4g} -> {f[-1]:.6g} in {len(f) - 1} iterations, {seconds:.2f} s CPU")
for name, g in (("initial guess", graph), ("optimized", optimized)):
    ate = absolute_trajectory_error(g.poses, truth["poses"])["rmse"]
    lm = np.sqrt(np.mean(np.sum((g.landmarks - truth["landmarks"]) ** 2, axis=1)))
    print(f"{name:>14}: position RMSE {ate:.3f} m, landmark RMSE {lm:.3f} m (the first pose is the true one)")
n_residuals = 3 * len(graph.edges) + 2 * len(graph.landmark_edges)
print(f"{n_residuals} residuals - {graph.state_size - 3} free parameters = {n_residuals - graph.state_size + 3}: "
      "the value F should reach when the noise model is right")

plot_objective_history({"bundled graph": history}, title="Bundled graph: objective F per Gauss-Newton iteration")
plt.show()

ax = new_axes("Bundled graph: optimized against the truth [m]", figsize=(8, 6))
ax.plot(*truth["poses"][:, :2].T, "-", color="black", linewidth=1.0, label="true path")
ax.scatter(*truth["landmarks"].T, marker="+", s=40, color="black", label="true landmarks")
plot_pose_graph(optimized, ax, color="tab:orange", label="optimized", loop_closures=False, legend=False)
ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1), fontsize="small")
plt.show()

# %% [markdown]
# **Question.** The objective falls by orders of magnitude in the first two steps, then barely changes. Which part of the error makes the problem non-linear, and why does a poor initial heading cost more iterations than a poor initial position? What would you expect from a single Gauss-Newton step if all headings were already right? Compare the final $F$ with the number of residuals minus free parameters printed above: what does it say about the noise model of the edges?
#
# *Your answer here.*

# %% [markdown]
# ## 8. Course graphs and real data: the Intel Research Lab and the Manhattan world
#
# The `graph_slam` data set (not part of robolab; `robolab.datasets.fetch("graph_slam")` downloads it, 2 MB) holds the two simulated graphs of the Freiburg Robot Mapping course (a pose graph of 400 poses, and a small pose-landmark graph) and two classic benchmarks: the **Intel Research Lab** (1728 poses, 4830 edges from odometry and scan matching, a real robot in a building with a ring corridor) and Olson's **Manhattan world M3500** (3500 poses, 5453 edges, synthetic, with a deliberately poor initial guess). There is no ground truth: a solver is judged by the objective it reaches and how fast. An established solver (GTSAM 4.3, Gauss-Newton from the same initial guesses, $F$ evaluated with the errors of this lab) reaches **359.997 on Intel in 5 iterations** and **137.913 on M3500 in 6**. The cell says so when the data set is not on disk.

# %%
from robolab.realdata.graph_slam import GTSAM_ANCHOR, REAL_GRAPHS, optimize_real_graphs

folder = locate("graph_slam")
if folder is None:
    print("The graph_slam data set is not on disk: robolab.datasets.fetch('graph_slam') downloads it.")
    real = None
else:
    course = optimize_real_graphs(optimize_graph, folder, names=("simulation-pose-pose.g2o", "simulation-pose-landmark.g2o"))
    real = optimize_real_graphs(optimize_graph, folder)
    for name, r in course.items():
        f = r["history"]["objective"]
        print(f"course graph {name}: F {f[0]:.4g} -> {f[-1]:.6g} in {len(f) - 1} iterations, {r['cpu_seconds']:.2f} s CPU")
    for name, r in real.items():
        f = r["history"]["objective"]
        f0, f_ref, it_ref = GTSAM_ANCHOR[name]
        print(f"{REAL_GRAPHS[name]}: F {f[0]:.4g} -> {f[-1]:.6g} in {len(f) - 1} iterations, {r['cpu_seconds']:.2f} s CPU "
              f"(GTSAM: {f_ref} in {it_ref}; yours differs by {100 * abs(f[-1] / f_ref - 1):.3f} %)")

# %%
if real is not None:
    plot_objective_history({**{f"course: {k}": v["history"] for k, v in course.items()},
                            **{REAL_GRAPHS[k]: v["history"] for k, v in real.items()}},
                           title="Course and real graphs: objective F per Gauss-Newton iteration")
    plt.show()

    fig, axes = panel_grid(4, panel=(5.5, 4.8), max_cols=2, title="Intel (top) and M3500 (bottom): initial guess and optimized")
    for row, name in enumerate(REAL_GRAPHS):
        plot_pose_graph(real[name]["initial"], axes[2 * row], title=f"{REAL_GRAPHS[name]}, initial guess",
                        loop_closures=False, legend=False, linewidth=0.6)
        plot_pose_graph(real[name]["optimized"], axes[2 * row + 1], title=f"{REAL_GRAPHS[name]}, optimized",
                        color="tab:orange", loop_closures=False, legend=False, linewidth=0.6)
    for ax in axes:
        ax.set_xlabel("x [m]"); ax.set_ylabel("y [m]"); ax.set_aspect("equal", adjustable="datalim")
    plt.show()

# %% [markdown]
# Why not the Intel map itself? The laser scans of the Intel data set (the CARMEN log read in lab 04) belong to a different recording of the same building: 910 scans with corrected poses, against the 1728 vertices of this graph, with no time stamps or ids that pair them. Without a correspondence the scans cannot be placed along *these* optimized poses, so the figure shows the trajectory before and after instead: the ring corridor and the rooms off it appear once the loop closures pull the odometry together.
#
# **Questions.**
#
# 1. Look at the sparsity patterns of section 5. How many non-zero entries does $H$ have per pose, and how does that number grow with the length of the run? Compare with the covariance matrix of EKF-SLAM, which is dense: what does that mean for the cost of one update in each method, for a map of $K$ landmarks?
#
#    *Your answer here.*
#
# 2. Why must one pose be fixed, and what happens to the result if you fix a different pose instead of the first? (Try it: the graph is the same up to what?)
#
#    *Your answer here.*
#
# 3. M3500's initial guess is poor. Gauss-Newton still converges here, but it is not guaranteed to: what could make it diverge, and what do Levenberg-Marquardt (a damped step, $(H + \lambda I)\,\Delta x = -b$) and robust kernels for wrong loop closures change?
#
#    *Your answer here.*
#
# 4. A filter (EKF-SLAM, FastSLAM) never revisits a past pose; graph-based SLAM re-linearises every edge at every iteration. Explain with this lab's figures why that matters after a loop closure.
#
#    *Your answer here.*
