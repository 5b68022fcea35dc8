"""Figures for lab 02, the beam model of range finders (Probabilistic Robotics 6.3).

Every function draws into ``ax``/``axes`` when given and otherwise makes a
titled, labelled figure; each returns the Axes it drew on (or an array of Axes).
Nothing here computes the model: the notebook passes in the values its own
functions produced.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import ListedColormap

from robolab.maps import OccupancyGrid
from robolab.plotting.core import legend_outside, new_axes, plot_map, plot_scan
from robolab.validation import as_array, check_positive

__all__ = [
    "plot_components",
    "plot_mixture",
    "plot_scan_on_map",
    "lattice_positions",
    "plot_likelihood_map",
    "plot_top_poses",
    "plot_weight_profiles",
]

_PANELS = (
    ("p_hit", "(a) Gaussian $p_{hit}$", "tab:blue"),
    ("p_short", "(b) Exponential $p_{short}$", "tab:orange"),
    ("p_max", "(c) Point mass $p_{max}$", "tab:green"),
    ("p_rand", "(d) Uniform $p_{rand}$", "tab:red"),
)


def _point_mass(ax, at, height, color, label=None):
    """A point mass drawn as a stem with a dot (its height is a probability, not a density)."""
    ax.vlines(at, 0.0, height, colors=color, linewidth=2.5, label=label)
    ax.plot([at], [height], "o", color=color)


def plot_components(z, components, z_star, z_max, axes=None, *, title=None):
    """The four error models of the beam model in four panels (Probabilistic Robotics, Figure 6.3).

    Parameters
    ----------
    z : array_like, shape (M,)
        Readings at which the densities were evaluated, metres.
    components : dict
        ``{"p_hit": (M,), "p_short": (M,), "p_max": (M,), "p_rand": (M,)}``, the
        values of each component at ``z``. ``p_max`` is drawn as a point mass
        at ``z_max`` (with the value the function returned there).
    z_star : float
        The expected range, metres (dashed line).
    z_max : float
        The maximum range, metres.
    axes : array of 4 Axes, optional
    title : str, optional
        Figure title.

    Returns
    -------
    numpy.ndarray of Axes, shape (2, 2)
    """
    z = as_array("z", z, ndim=1, finite=True)
    z_max = check_positive("z_max", z_max)
    if axes is None:
        fig, axes = plt.subplots(2, 2, figsize=(10, 6.5), sharex=True, constrained_layout=True)
        fig.suptitle(
            title or f"Beam model components for $z^*$ = {z_star:g} m, $z_{{max}}$ = {z_max:g} m"
        )
    axes = np.asarray(axes).reshape(2, 2)
    for ax, (key, label, color) in zip(axes.ravel(), _PANELS, strict=True):
        if key not in components:
            raise ValueError(f"components must have the key {key!r}")
        values = as_array(f"components[{key!r}]", components[key], shape=(z.size,))
        if key == "p_max":
            at = np.isclose(z, z_max, rtol=0, atol=0)
            height = float(values[at].max()) if at.any() else 1.0
            _point_mass(ax, z_max, height, color, label="$I(z = z_{max})$ (a probability)")
            ax.plot(z[~at], values[~at], color=color, linewidth=1)
            ax.set_ylabel("probability")
            ax.legend(loc="upper left", fontsize="small")
        else:
            ax.plot(z, values, color=color)
            ax.fill_between(z, values, color=color, alpha=0.2)
            ax.set_ylabel("density [1/m]")
        ax.axvline(z_star, color="k", linestyle="--", linewidth=0.8)
        ax.set_title(label)
        ax.set_xlabel("measured range $z$ [m]")
        ax.set_xlim(min(0.0, z.min()), max(z.max(), z_max) * 1.04)
        ax.set_ylim(bottom=0.0)
    return axes


def plot_mixture(z, p, z_star, z_max, w_max, ax=None, *, title=None, label="beam model"):
    """The final distribution of one beam: the mixture density plus the point mass at ``z_max``.

    Parameters
    ----------
    z : array_like, shape (M,)
        Readings, metres, below ``z_max`` (the continuous part).
    p : array_like, shape (M,)
        The mixture at ``z`` (density, 1/m).
    z_star, z_max : float
        Expected and maximum range, metres.
    w_max : float
        The weight of ``p_max``: the probability of a max-range reading, drawn as a stem.
    ax : Axes, optional
    title, label : str, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    z = as_array("z", z, ndim=1, finite=True)
    p = as_array("p", p, shape=(z.size,))
    if ax is None:
        ax = new_axes(
            title or f"Final distribution $p(z \\mid x, m)$ for $z^*$ = {z_star:g} m",
            "measured range $z$ [m]",
            "density [1/m] (stem: probability)",
            equal=False,
            figsize=(8.0, 4.0),
        )
    elif title:
        ax.set_title(title)
    ax.plot(z, p, color="tab:purple", label=label)
    ax.fill_between(z, p, color="tab:purple", alpha=0.15)
    _point_mass(ax, z_max, w_max, "tab:green", label=f"point mass $z_{{max}}$ weight = {w_max:g}")
    ax.axvline(z_star, color="k", linestyle="--", linewidth=0.8, label=f"$z^*$ = {z_star:g} m")
    ax.set_xlabel("measured range $z$ [m]")
    ax.set_ylabel("density [1/m] (stem: probability)")
    ax.set_xlim(0.0, z_max * 1.02)
    ax.set_ylim(bottom=0.0)
    ax.legend(loc="upper right", fontsize="small")
    return ax


def plot_scan_on_map(grid, pose, ranges, angles, max_range, ax=None, *, expected=None, title=None):
    """The maze, the robot and its scan; optionally the ray-cast expected ranges too.

    Parameters
    ----------
    grid : OccupancyGrid
    pose : array_like, shape (3,)
        The sensor pose ``(x, y, theta)``, metres and radians.
    ranges : array_like, shape (B,)
        Measured ranges, metres; readings at ``max_range`` are drawn as grey rays.
    angles : array_like, shape (B,)
        Beam angles relative to the heading, radians.
    max_range : float
    ax : Axes, optional
    expected : array_like, shape (B,), optional
        Ray-cast ranges ``z*`` drawn as hollow circles.
    title : str, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    pose = as_array("pose", pose, shape=(3,), finite=True)
    ranges = as_array("ranges", ranges, ndim=1)
    angles = as_array("angles", angles, shape=(ranges.size,), finite=True)
    max_range = check_positive("max_range", max_range)
    if ax is None:
        ax = new_axes(title or "Simulated scan in the maze", figsize=(6.5, 6.5))
    elif title:
        ax.set_title(title)
    plot_map(grid, ax)
    plot_scan(
        (ranges, angles),
        ax,
        origin=pose,
        rays=True,
        max_range=max_range,
        color="tab:green",
        size=12,
        label="measured $z$",
    )
    at_max = ranges >= max_range
    if at_max.any():
        a = pose[2] + angles[at_max]
        ends = pose[:2] + max_range * np.stack([np.cos(a), np.sin(a)], -1)
        for e in ends:
            ax.plot([pose[0], e[0]], [pose[1], e[1]], color="0.6", linewidth=0.6, linestyle=":")
        ax.plot([], [], color="0.6", linestyle=":", label="max-range reading")
    if expected is not None:
        exp = as_array("expected", expected, shape=(ranges.size,), finite=True)
        a = pose[2] + angles
        pts = pose[:2] + exp[:, None] * np.stack([np.cos(a), np.sin(a)], -1)
        ax.scatter(
            pts[:, 0],
            pts[:, 1],
            s=30,
            facecolors="none",
            edgecolors="tab:blue",
            label="ray cast $z^*$",
        )
    ax.annotate(
        "",
        xy=pose[:2] + 0.5 * np.array([np.cos(pose[2]), np.sin(pose[2])]),
        xytext=pose[:2],
        arrowprops={"arrowstyle": "->", "color": "tab:red", "lw": 2},
    )
    legend_outside(ax)
    ax.set_aspect("equal", adjustable="box")
    left, right, bottom, top = grid.extent
    ax.set_xlim(left, right)
    ax.set_ylim(bottom, top)
    return ax


def lattice_positions(grid, spacing):
    """Positions on a square lattice over ``grid``, at cell centres, for a heat map.

    Parameters
    ----------
    grid : OccupancyGrid
        A map whose origin has no yaw.
    spacing : float
        Lattice spacing in metres, rounded to a whole number of cells (>= 1).

    Returns
    -------
    xs : numpy.ndarray, shape (nx,)
    ys : numpy.ndarray, shape (ny,)
    positions : numpy.ndarray, shape (ny * nx, 2)
        ``(x, y)`` row by row (y outer, x inner), so values over ``positions``
        reshape to ``(ny, nx)`` for :func:`plot_likelihood_map`.
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    step = max(1, int(round(check_positive("spacing", spacing) / grid.resolution)))
    rows = np.arange(step // 2, grid.shape[0], step)
    cols = np.arange(step // 2, grid.shape[1], step)
    xs = grid.cell_to_world(np.stack([np.zeros_like(cols), cols], -1))[:, 0]
    ys = grid.cell_to_world(np.stack([rows, np.zeros_like(rows)], -1))[:, 1]
    xx, yy = np.meshgrid(xs, ys)
    return xs, ys, np.stack([xx.ravel(), yy.ravel()], -1)


def plot_likelihood_map(
    grid,
    xs,
    ys,
    values,
    ax=None,
    *,
    true_pose=None,
    title=None,
    label="max over headings of log p(z | x, m)",
    floor=None,
):
    """Heat map of a log-likelihood over positions, on top of the map.

    Parameters
    ----------
    grid : OccupancyGrid
    xs, ys : array_like, shape (nx,), (ny,)
        The lattice (see :func:`lattice_positions`).
    values : array_like, shape (ny, nx)
        Log-likelihood per position (e.g. the max over headings).
    ax : Axes, optional
    true_pose : array_like, shape (3,), optional
        Marked with a star and an arrow.
    title, label : str
    floor : float, optional
        Values below ``max - floor`` are clipped, so that the colour scale shows
        the plausible region (default: 60 nats below the maximum).

    Returns
    -------
    matplotlib.axes.Axes
    """
    xs = as_array("xs", xs, ndim=1, finite=True)
    ys = as_array("ys", ys, ndim=1, finite=True)
    v = as_array("values", values, shape=(ys.size, xs.size))
    if ax is None:
        ax = new_axes(title or "Where could the robot be? Scan log-likelihood", figsize=(7.5, 6.5))
    elif title:
        ax.set_title(title)
    top = np.nanmax(v)
    low = top - (60.0 if floor is None else float(floor))
    dx = xs[1] - xs[0] if xs.size > 1 else grid.resolution
    dy = ys[1] - ys[0] if ys.size > 1 else grid.resolution
    im = ax.imshow(
        np.clip(v, low, top),
        origin="lower",
        cmap="magma",
        vmin=low,
        vmax=top,
        extent=(xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2),
        interpolation="nearest",
    )
    walls = np.ma.masked_where(~grid.occupied, np.ones(grid.shape))
    ax.imshow(
        walls,
        origin="lower",
        extent=grid.extent,
        cmap=ListedColormap(["lightsteelblue"]),
        interpolation="nearest",
    )
    plt.colorbar(im, ax=ax, label=f"{label} [nats]")
    ax.plot([], [], "s", color="lightsteelblue", label="walls")
    if true_pose is not None:
        tp = as_array("true_pose", true_pose, shape=(3,), finite=True)
        ax.plot(  # hollow, so that the peak under it stays visible
            tp[0],
            tp[1],
            "o",
            markerfacecolor="none",
            markeredgecolor="tab:cyan",
            markeredgewidth=2.0,
            markersize=14,
            label="true pose",
        )
        ax.annotate(
            "",
            xy=tp[:2] + 0.6 * np.array([np.cos(tp[2]), np.sin(tp[2])]),
            xytext=tp[:2],
            arrowprops={"arrowstyle": "->", "color": "tab:cyan", "lw": 2},
        )
    ax.legend(loc="upper right", fontsize="small")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return ax


def plot_top_poses(grid, rankings, ax=None, *, true_pose=None, title=None, zoom=None):
    """The best-ranked poses of several models on the map, one colour per model.

    Parameters
    ----------
    grid : OccupancyGrid
    rankings : dict
        ``{label: poses (K, 3)}``, each model's K best poses, best first (the
        best is drawn larger).
    ax : Axes, optional
    true_pose : array_like, shape (3,), optional
    title : str, optional
    zoom : float, optional
        Show only a square of this half-width (metres) around ``true_pose``.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        ax = new_axes(title or "Best-ranked poses of each model", figsize=(6.5, 6.5))
    elif title:
        ax.set_title(title)
    plot_map(grid, ax)
    colors = ("tab:blue", "tab:orange", "tab:purple", "tab:brown")
    markers = ("o", "s", "^", "D")
    for i, (label, poses) in enumerate(rankings.items()):
        p = as_array(f"rankings[{label!r}]", poses, ndim=2, finite=True)
        if p.shape[1] != 3:
            raise ValueError(f"rankings[{label!r}] must have shape (K, 3), got {p.shape}")
        c = colors[i % len(colors)]
        length = 0.4 if zoom is None else 0.15 * zoom
        ax.quiver(
            p[:, 0],
            p[:, 1],
            length * np.cos(p[:, 2]),
            length * np.sin(p[:, 2]),
            color=c,
            angles="xy",
            scale_units="xy",
            scale=1.0,
            width=0.005,
        )
        ax.scatter(
            p[1:, 0], p[1:, 1], s=25, color=c, marker=markers[i % 4], label=f"{label}: top {len(p)}"
        )
        ax.scatter(
            p[:1, 0],
            p[:1, 1],
            s=140,
            color=c,
            marker=markers[i % 4],
            edgecolors="k",
            label=f"{label}: best",
        )
    if true_pose is not None:
        tp = as_array("true_pose", true_pose, shape=(3,), finite=True)
        ax.plot(
            tp[0],
            tp[1],
            "*",
            color="tab:cyan",
            markersize=18,
            markeredgecolor="k",
            label="true pose",
        )
    ax.legend(loc="upper right", fontsize="small")
    ax.set_aspect("equal", adjustable="box")
    if zoom is not None and true_pose is not None:
        half = check_positive("zoom", zoom)
        ax.set_xlim(tp[0] - half, tp[0] + half)
        ax.set_ylim(tp[1] - half, tp[1] + half)
    else:
        left, right, bottom, top = grid.extent
        ax.set_xlim(left, right)
        ax.set_ylim(bottom, top)
    return ax


def plot_weight_profiles(weights, ax=None, *, title=None):
    """Normalized particle weights sorted from largest to smallest, one line per model (log scale).

    Parameters
    ----------
    weights : dict
        ``{label: weights (M,)}``, non-negative; each is normalized to sum 1.
    ax : Axes, optional
    title : str, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        ax = new_axes(
            title or "How concentrated are the weights?",
            "rank of the pose (best first)",
            "normalized weight",
            equal=False,
            figsize=(6.5, 4.5),
        )
    elif title:
        ax.set_title(title)
    for label, w in weights.items():
        w = as_array(f"weights[{label!r}]", w, ndim=1, finite=True, nonnegative=True)
        w = np.sort(w / w.sum())[::-1]
        ax.plot(np.arange(1, w.size + 1), np.maximum(w, 1e-300), label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("rank of the pose (best first)")
    ax.set_ylabel("normalized weight")
    ax.set_ylim(1e-30, 2.0)
    ax.legend(fontsize="small")
    return ax
