"""Figures for lab 00, bags and frames.

Every function draws into the Axes it is given (or makes a titled, labelled
figure) and returns what it drew on. Points and poses come in as plain arrays
computed by the notebook (with the student's functions); the figures only draw.
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes

from robolab.geometry import compose
from robolab.maps import OccupancyGrid
from robolab.plotting.core import new_axes, plot_map
from robolab.validation import as_array, check_positive

__all__ = ["draw_frame", "plot_scan_in_frames", "plot_scan_cloud", "plot_message_timeline"]


def _points(name: str, value) -> np.ndarray:
    pts = as_array(name, value, ndim=2)
    if pts.shape[1] != 2:
        raise ValueError(f"{name} must have shape (P, 2), got {pts.shape}")
    return pts


def draw_frame(
    pose,
    ax: Axes,
    label: str | None = None,
    *,
    length: float = 0.3,
    label_offset: tuple[float, float] = (-6.0, -12.0),
) -> Axes:
    """Draw a coordinate frame: its x axis (red) and y axis (green) at ``pose``.

    Parameters
    ----------
    pose : array_like, shape (3,)
        The frame's pose ``(x, y, theta)`` in the plotted frame, metres and radians.
    ax : Axes
        Where to draw.
    label : str, optional
        The frame's name, written next to its origin.
    length : float
        Length of the axis arrows, metres.
    label_offset : (float, float)
        Where the label goes relative to the origin, in points; a negative x offset
        right-aligns the label (so two frames close together can label both sides).

    Returns
    -------
    matplotlib.axes.Axes
    """
    x, y, th = as_array("pose", pose, shape=(3,), finite=True)
    length = check_positive("length", length)
    for angle, color in ((th, "tab:red"), (th + np.pi / 2, "tab:green")):
        ax.annotate(
            "",
            xy=(x + length * np.cos(angle), y + length * np.sin(angle)),
            xytext=(x, y),
            arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.8},
            zorder=5,
        )
    ax.plot(x, y, "ko", markersize=3, zorder=6)
    if label:
        ax.annotate(
            label,
            (x, y),
            xytext=label_offset,
            textcoords="offset points",
            ha="right" if label_offset[0] < 0 else "left",
            fontsize="small",
            zorder=6,
        )
    ax.update_datalim([[x - length, y - length], [x + length, y + length]])
    return ax


def plot_scan_in_frames(
    laser_points,
    base_points,
    odom_points,
    laser_in_base,
    base_in_odom,
    *,
    laser_frame: str = "base_laser_link",
    stamp: float | None = None,
    axes=None,
    size: float = 4.0,
    frame_length: float = 0.8,
):
    """One scan drawn three times: in the laser frame, in ``base_link`` and in ``odom``.

    Each panel also draws the frames known there (red x axis, green y axis), so
    the reader sees the same wall move as the point of view changes.

    Parameters
    ----------
    laser_points, base_points, odom_points : array_like, shape (P, 2)
        The scan's endpoints expressed in the laser frame, ``base_link`` and ``odom``.
    laser_in_base : array_like, shape (3,)
        The laser's pose in ``base_link`` (the mount).
    base_in_odom : array_like, shape (3,)
        The robot's pose in ``odom`` at the scan's stamp.
    laser_frame : str
        Name of the laser frame, for the titles.
    stamp : float, optional
        Seconds since the start of the bag, for the figure title.
    axes : sequence of 3 Axes, optional
        Where to draw; a new 1 x 3 figure when omitted.
    size : float
        Marker area, points^2.
    frame_length : float
        Length of the drawn frame axes, metres.

    Returns
    -------
    numpy.ndarray of 3 Axes
    """
    pts = [
        _points("laser_points", laser_points),
        _points("base_points", base_points),
        _points("odom_points", odom_points),
    ]
    mount = as_array("laser_in_base", laser_in_base, shape=(3,), finite=True)
    robot = as_array("base_in_odom", base_in_odom, shape=(3,), finite=True)
    if axes is None:
        fig, axes = plt.subplots(1, 3, figsize=(13, 4.6))
        when = f" at t = {stamp:.1f} s" if stamp is not None else ""
        fig.suptitle(f"One laser scan{when} in three frames")
    axes = np.asarray(axes, dtype=object).ravel()
    if axes.size != 3:
        raise ValueError(f"axes must hold 3 Axes, got {axes.size}")
    below, above = (-6.0, -12.0), (6.0, 6.0)  # base_link and the laser are only cm apart
    frames = [
        [((0.0, 0.0, 0.0), laser_frame, above)],
        [((0.0, 0.0, 0.0), "base_link", below), (mount, laser_frame, above)],
        [
            ((0.0, 0.0, 0.0), "odom", below),
            (robot, "base_link", below),
            (compose(robot, mount), laser_frame, above),
        ],
    ]
    names = [laser_frame, "base_link", "odom"]
    for ax, p, drawn, name in zip(axes, pts, frames, names, strict=True):
        ax.scatter(p[:, 0], p[:, 1], s=size, c="tab:blue", linewidths=0, label="endpoints")
        for pose, label, offset in drawn:
            draw_frame(pose, ax, label, length=frame_length, label_offset=offset)
        ax.set_title(f"in the {name} frame")
        ax.set_xlabel(f"x_{name} [m]")
        ax.set_ylabel(f"y_{name} [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    return axes


def plot_scan_cloud(
    points,
    times,
    ax: Axes | None = None,
    *,
    grid: OccupancyGrid | None = None,
    path=None,
    title: str = "Scan endpoints coloured by time",
    cmap: str = "viridis",
    size: float = 0.5,
    colorbar: bool = True,
    vmax: float | None = None,
) -> Axes:
    """Scan endpoints of many scans, coloured by time, optionally over a map and a path.

    Parameters
    ----------
    points : array_like, shape (P, 2)
        Endpoints in the plotted frame (e.g. ``map``), metres.
    times : array_like, shape (P,)
        Time of each endpoint's scan, seconds since the start.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    grid : OccupancyGrid, optional
        A map drawn underneath (faded so the points stand out); the view is
        limited to the map's extent.
    path : array_like, shape (T, 2) or (T, 3), optional
        The robot's path, drawn as a thin black line.
    title : str
        Axes title.
    cmap : str
        Colormap of time.
    size : float
        Marker area, points^2.
    colorbar : bool
        Add a colorbar labelled with the time.
    vmax : float, optional
        Time at the top of the colour scale (default: the largest time).

    Returns
    -------
    matplotlib.axes.Axes
    """
    pts = _points("points", points)
    t = as_array("times", times, shape=(len(pts),), finite=True)
    ax = new_axes(title, figsize=(9.0, 6.0)) if ax is None else ax
    ax.set_title(title)
    if grid is not None:
        plot_map(grid, ax, alpha=0.45)
    sc = ax.scatter(
        pts[:, 0],
        pts[:, 1],
        c=t,
        s=size,
        cmap=cmap,
        vmin=0.0,
        vmax=vmax,
        linewidths=0,
        rasterized=True,
    )
    if path is not None:
        xy = as_array("path", path, ndim=2, finite=True)
        if xy.shape[1] not in (2, 3):
            raise ValueError(f"path must have shape (T, 2) or (T, 3), got {xy.shape}")
        ax.plot(xy[:, 0], xy[:, 1], "k-", lw=1.0, label="robot path")
        ax.plot(xy[0, 0], xy[0, 1], "k^", ms=6, label="start")
        ax.legend(loc="lower right", fontsize="small")
    if colorbar:
        ax.figure.colorbar(sc, ax=ax, label="time since start [s]", shrink=0.8)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if grid is not None:
        left, right, bottom, top = grid.extent
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlim(left, right)
        ax.set_ylim(bottom, top)
    else:
        ax.set_aspect("equal", adjustable="datalim")
    return ax


def plot_message_timeline(
    stamps_by_topic: Mapping[str, object],
    *,
    start: float | None = None,
    duration: float = 1.0,
    ax: Axes | None = None,
    title: str = "Messages in the bag over time",
) -> Axes:
    """One row of ticks per topic at its messages' times: the bag as ``rqt_bag`` shows it.

    Parameters
    ----------
    stamps_by_topic : mapping of str to array_like (N,)
        Record times (seconds) of each topic's messages.
    start : float, optional
        Time shown as 0 (default: the earliest stamp).
    duration : float
        Seconds shown after ``start``.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    title : str
        Axes title.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if not stamps_by_topic:
        raise ValueError("stamps_by_topic must hold at least one topic")
    stamps = {
        str(k): as_array(f"stamps_by_topic[{k!r}]", v, ndim=1, finite=True)
        for k, v in stamps_by_topic.items()
    }
    duration = check_positive("duration", duration)
    t0 = min(float(s.min()) for s in stamps.values() if s.size) if start is None else float(start)
    if ax is None:
        ax = new_axes(
            title,
            xlabel="time since start [s]",
            ylabel="topic",
            equal=False,
            figsize=(9.0, 0.6 * len(stamps) + 1.5),
        )
    else:
        ax.set_title(title)
        ax.set_xlabel("time since start [s]")
    names = list(stamps)
    for row, name in enumerate(names):
        s = stamps[name] - t0
        s = s[(s >= 0) & (s <= duration)]
        ax.vlines(s, row - 0.35, row + 0.35, color=f"C{row}", lw=1.5)
    ax.set_yticks(range(len(names)), names)
    ax.set_ylim(-0.6, len(names) - 0.4)
    ax.set_xlim(-0.01 * duration, 1.01 * duration)
    ax.grid(True, axis="x", alpha=0.3)
    return ax
