"""Figures for lab 04, mapping with raw odometry.

Every function draws into the Axes it is given or makes a titled, labelled
figure, and returns the Axes it drew on (an array of Axes for grids of panels).
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np

from robolab.geometry import angle_diff
from robolab.maps import OccupancyGrid
from robolab.plotting.core import legend_outside, panel_grid, plot_map, plot_poses
from robolab.validation import as_array

__all__ = [
    "plot_map_snapshots",
    "plot_map_comparison",
    "plot_trajectories",
    "plot_odometry_drift",
    "plot_beam_cells",
]


def _poses(name, value):
    arr = as_array(name, value, ndim=2, finite=True)
    if arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (T, 3), got {arr.shape}")
    return arr


def plot_map_snapshots(
    grids: Sequence[OccupancyGrid],
    labels: Sequence[str],
    *,
    paths: Sequence[np.ndarray] | None = None,
    title: str = "Counting map",
    axes=None,
    panel_width: float = 4.2,
):
    """Draw several maps side by side, e.g. the map at 2 s, 8 s, 20 s and the end.

    Parameters
    ----------
    grids : sequence of OccupancyGrid
        The maps (occupancy in [0, 1], -1 unknown).
    labels : sequence of str
        One panel title per map (e.g. ``"t = 2 s"``).
    paths : sequence of (T, 3) arrays, optional
        The robot's path (as the map was built from) drawn over each map.
    title : str
        Figure title.
    axes : array of Axes, optional
        Where to draw; a new one-row figure when omitted.
    panel_width : float
        Width of one panel in inches, for a new figure.

    Returns
    -------
    numpy.ndarray of Axes
    """
    grids = list(grids)
    labels = list(labels)
    if not grids or len(labels) != len(grids):
        raise ValueError(f"give one label per map: {len(grids)} maps, {len(labels)} labels")
    if paths is not None and len(paths) != len(grids):
        raise ValueError(f"give one path per map: {len(grids)} maps, {len(paths)} paths")
    if axes is None:
        fig, axes = panel_grid(
            len(grids),
            panel=(panel_width, panel_width * 0.75),
            title=title,
            constrained_layout=True,
        )
    axes = np.atleast_1d(axes)
    for k, (grid, label, ax) in enumerate(zip(grids, labels, axes, strict=True)):
        plot_map(grid, ax, title=label)
        if paths is not None and len(paths[k]):
            plot_poses(
                _poses("paths[k]", paths[k]),
                ax,
                color="tab:red",
                arrows=False,
                linewidth=1.0,
                label="robot path",
            )
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    return axes


def plot_map_comparison(
    left: OccupancyGrid,
    right: OccupancyGrid,
    *,
    left_title: str,
    right_title: str,
    title: str,
    left_path=None,
    right_path=None,
    true_path=None,
):
    """Two maps side by side with their paths (and the true path dashed on both).

    Parameters
    ----------
    left, right : OccupancyGrid
        The maps, e.g. built from raw odometry and from ground truth.
    left_title, right_title, title : str
        Panel titles and the figure title.
    left_path, right_path, true_path : (T, 3) arrays, optional
        Paths drawn on the left, the right, and both panels.

    Returns
    -------
    numpy.ndarray of Axes, shape (2,)
    """
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6), constrained_layout=True)
    fig.suptitle(title)
    for ax, grid, name, path in (
        (axes[0], left, left_title, left_path),
        (axes[1], right, right_title, right_path),
    ):
        plot_map(grid, ax, title=name)
        if true_path is not None:
            plot_poses(
                _poses("true_path", true_path),
                ax,
                color="tab:green",
                arrows=False,
                linestyle="--",
                linewidth=1.0,
                label="true path",
            )
        if path is not None:
            plot_poses(
                _poses("path", path),
                ax,
                color="tab:red",
                arrows=False,
                linewidth=1.0,
                label="path used for mapping",
            )
        ax.legend(loc="upper right", fontsize="small")
    return axes


def plot_trajectories(
    true_poses,
    odom_poses,
    grid: OccupancyGrid | None = None,
    ax=None,
    *,
    title: str = "Ground truth and raw odometry",
):
    """The true path and the raw-odometry path, over a map when given.

    Parameters
    ----------
    true_poses, odom_poses : (T, 3) arrays
        Poses in the map frame (odometry anchored at the first true pose).
    grid : OccupancyGrid, optional
        Drawn underneath.
    ax : Axes, optional
    title : str

    Returns
    -------
    Axes
    """
    true_poses = _poses("true_poses", true_poses)
    odom_poses = _poses("odom_poses", odom_poses)
    if ax is None:
        _, ax = plt.subplots(figsize=(9, 5.5))
    if grid is not None:
        plot_map(grid, ax)
    plot_poses(
        true_poses,
        ax,
        color="tab:green",
        label="ground truth",
        arrow_every=max(len(true_poses) // 12, 1),
    )
    plot_poses(
        odom_poses,
        ax,
        color="tab:red",
        label="raw odometry",
        arrow_every=max(len(odom_poses) // 12, 1),
    )
    ax.plot(*true_poses[0, :2], "ko", label="start")
    ax.set_title(title)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper right")
    return ax


def plot_odometry_drift(
    t,
    true_poses,
    odom_poses,
    *,
    title: str = "Raw odometry drift against ground truth",
    marks: Sequence[float] = (),
):
    """Position error (m) and heading error (degrees) of odometry against time.

    Parameters
    ----------
    t : (T,) array
        Seconds since the start.
    true_poses, odom_poses : (T, 3) arrays
        Poses at ``t`` in the map frame.
    title : str
    marks : sequence of float
        Times to mark with vertical lines (e.g. the snapshot times 2, 8, 20 s).

    Returns
    -------
    numpy.ndarray of Axes, shape (2,)
    """
    t = as_array("t", t, ndim=1, finite=True)
    true_poses = _poses("true_poses", true_poses)
    odom_poses = _poses("odom_poses", odom_poses)
    if not (len(t) == len(true_poses) == len(odom_poses)):
        raise ValueError(
            f"t, true_poses and odom_poses must have the same length, got "
            f"{len(t)}, {len(true_poses)}, {len(odom_poses)}"
        )
    pos_err = np.hypot(*(odom_poses[:, :2] - true_poses[:, :2]).T)
    head_err = np.degrees(angle_diff(odom_poses[:, 2], true_poses[:, 2]))
    fig, axes = plt.subplots(1, 2, figsize=(12, 3.8), constrained_layout=True)
    fig.suptitle(title)
    axes[0].plot(t, pos_err, color="tab:red")
    axes[0].set_title("position error |(x, y)_odom - (x, y)_true|")
    axes[0].set_xlabel("time [s]")
    axes[0].set_ylabel("position error [m]")
    axes[1].plot(t, head_err, color="tab:purple")
    axes[1].axhline(0.0, color="0.6", linewidth=0.8)
    axes[1].set_title("heading error theta_odom - theta_true")
    axes[1].set_xlabel("time [s]")
    axes[1].set_ylabel("heading error [deg]")
    for ax in axes:
        for m in marks:
            ax.axvline(m, color="0.5", linestyle=":", linewidth=1.0)
        ax.grid(alpha=0.3)
    return axes


def plot_beam_cells(
    start, ends, cells, beam, ax=None, *, title: str = "Cells touched by each beam (supercover)"
):
    """Draw beams in continuous cell coordinates and shade the cells each one touches.

    Parameters
    ----------
    start : (2,) array
        Common start ``(row, col)`` in cell units.
    ends : (B, 2) array
        Beam ends ``(row, col)``.
    cells : (N, 2) int array
        ``(row, col)`` of the touched cells (as returned by ``beam_cells``).
    beam : (N,) int array
        Beam index of each cell.
    ax : Axes, optional
    title : str

    Returns
    -------
    Axes
    """
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle

    start = as_array("start", start, shape=(2,), finite=True)
    ends = as_array("ends", ends, ndim=2, finite=True)
    cells = as_array("cells", cells, ndim=2)
    beam = as_array("beam", beam, shape=(cells.shape[0],))
    if ax is None:
        _, ax = plt.subplots(figsize=(5.5, 5.5))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for b in range(len(ends)):
        color = colors[b % len(colors)]
        mine = cells[beam == b]
        squares = [Rectangle((c, r), 1.0, 1.0) for r, c in mine]
        ax.add_collection(PatchCollection(squares, facecolor=color, alpha=0.3, edgecolor=color))
        ax.plot(
            [start[1], ends[b, 1]],
            [start[0], ends[b, 0]],
            "-",
            color=color,
            lw=1.5,
            label=f"beam {b}: {len(mine)} cells",
        )
    everything = np.vstack([cells, start[None], ends])
    lo, hi = np.floor(everything.min(0)) - 1, np.ceil(everything.max(0)) + 1
    ax.set_xlim(lo[1], hi[1])
    ax.set_ylim(lo[0], hi[0])
    ax.set_xticks(np.arange(lo[1], hi[1] + 1))
    ax.set_yticks(np.arange(lo[0], hi[0] + 1))
    ax.grid(True, color="0.7")
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.set_xlabel("col [cells]")
    ax.set_ylabel("row [cells]")
    legend_outside(ax)
    return ax
