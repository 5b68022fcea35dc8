"""Figures of lab 09, graph-based SLAM: the graph, the sparsity of H, the objective per iteration.

Built on :mod:`robolab.plotting.core`; every function takes an optional Axes,
makes a titled, labelled one when omitted, and returns it.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection

from robolab.datasets.g2o import PoseGraph
from robolab.plotting.layout import _axes, legend_outside, new_axes

__all__ = ["plot_pose_graph", "plot_sparsity", "plot_objective_history"]


def plot_pose_graph(
    graph: PoseGraph,
    ax: Axes | None = None,
    *,
    title: str | None = None,
    color: str = "tab:blue",
    label: str = "poses",
    loop_closures: bool = True,
    landmarks: bool = True,
    linewidth: float = 1.0,
    legend: bool = True,
) -> Axes:
    """Draw a graph: the path through the poses, loop closures, landmarks and their edges.

    Edges between poses ``i`` and ``i + 1`` are the path; every other pose-pose edge
    is drawn as a thin grey line (a loop closure); pose-landmark edges as faint green
    lines to the landmarks (crosses).
    """
    if not isinstance(graph, PoseGraph):
        raise TypeError(f"graph must be a PoseGraph, got {type(graph).__name__}")
    ax = _axes(ax, "Pose graph", title)
    p = graph.poses
    if loop_closures and len(graph.edges):
        i, j = graph.edges.T
        loops = np.abs(i - j) != 1
        if loops.any():
            segs = np.stack([p[i[loops], :2], p[j[loops], :2]], 1)
            ax.add_collection(
                LineCollection(
                    segs,
                    colors="0.55",
                    linewidths=0.5,
                    alpha=0.5,
                    label=f"loop closures ({int(loops.sum())})",
                )
            )
    if landmarks and graph.n_landmarks:
        if len(graph.landmark_edges):
            segs = np.stack(
                [p[graph.landmark_edges[:, 0], :2], graph.landmarks[graph.landmark_edges[:, 1]]], 1
            )
            ax.add_collection(
                LineCollection(
                    segs,
                    colors="tab:green",
                    linewidths=0.5,
                    alpha=0.35,
                    label=f"landmark edges ({len(segs)})",
                )
            )
        ax.scatter(
            *graph.landmarks.T,
            marker="x",
            s=25,
            color="tab:green",
            zorder=3,
            label=f"landmarks ({graph.n_landmarks})",
        )
    ax.plot(
        p[:, 0], p[:, 1], "-", color=color, linewidth=linewidth, label=f"{label} ({graph.n_poses})"
    )
    ax.autoscale_view()
    if legend:
        legend_outside(ax)
    return ax


def plot_sparsity(
    H, ax: Axes | None = None, *, title: str | None = None, n_poses: int | None = None
) -> Axes:
    """The non-zero pattern of a (sparse) matrix as an image: black where an entry is non-zero.

    With ``n_poses``, a line marks where the pose block ends and the landmark block starts.
    """
    if hasattr(H, "tocoo"):
        coo = H.tocoo()
        shape, rows, cols = coo.shape, coo.row[coo.data != 0], coo.col[coo.data != 0]
    else:
        dense = np.asarray(H, dtype=float)
        shape = dense.shape
        rows, cols = np.nonzero(dense)
    if ax is None:
        ax = new_axes(
            title or "Non-zero pattern of H",
            "column (state index)",
            "row (state index)",
            figsize=(6, 5.5),
        )
    elif title is not None:
        ax.set_title(title)
    # one image pixel per entry up to 600 x 600; larger matrices are binned
    bins = min(max(shape), 600)
    image, _, _ = np.histogram2d(rows, cols, bins=bins, range=[[0, shape[0]], [0, shape[1]]])
    ax.imshow(image > 0, cmap="Greys", interpolation="nearest", extent=(0, shape[1], shape[0], 0))
    if n_poses is not None and 3 * n_poses < shape[0]:
        for f in (ax.axhline, ax.axvline):
            f(3 * n_poses, color="tab:red", linewidth=0.8)
    return ax


def plot_objective_history(
    histories: dict, ax: Axes | None = None, *, title: str | None = None
) -> Axes:
    """The objective F per Gauss-Newton iteration (log scale), one line per run.

    ``histories`` maps a label to an ``objective`` array (or a history dict holding one).
    """
    if ax is None:
        ax = new_axes(
            title or "Objective per Gauss-Newton iteration",
            "iteration",
            "objective F (sum of e^T Omega e, no unit)",
            equal=False,
            figsize=(7, 4.5),
        )
    elif title is not None:
        ax.set_title(title)
    for name, h in histories.items():
        f = np.asarray(h["objective"] if isinstance(h, dict) else h, dtype=float)
        ax.semilogy(np.arange(len(f)), f, "o-", markersize=4, label=name)
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.grid(True, which="major", alpha=0.4)
    ax.legend(loc="upper right", fontsize="small")
    return ax
