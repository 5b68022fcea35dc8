"""Core figures shared by every lab: maps, poses, particles, landmarks, ellipses, scans.

Every function draws into an existing Axes when given one (``ax=...``) and
otherwise makes a new titled, labelled figure with :func:`new_axes`. Each
returns what it drew on (the Axes) -- or, for :func:`plot_covariance_ellipse`,
the artist -- so that callers can compose figures. None of them calls
``plt.show()``.

Units follow the project conventions: metres and radians; world axes are
labelled ``x [m]`` and ``y [m]`` and drawn with an equal aspect ratio.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import EllipseCollection
from matplotlib.colors import Colormap
from matplotlib.patches import Ellipse
from matplotlib.transforms import Affine2D

from robolab.geometry import transform_points
from robolab.maps import UNKNOWN, OccupancyGrid
from robolab.plotting.layout import (  # noqa: F401 - re-exported: labs import them from core
    LEGEND_MARKER_AREA,
    NOTEBOOK_WIDTH,
    _axes,
    legend_outside,
    new_axes,
    panel_grid,
)
from robolab.validation import as_array, as_poses, check_positive

__all__ = [
    "new_axes",
    "panel_grid",
    "legend_outside",
    "plot_map",
    "plot_poses",
    "plot_particles",
    "plot_landmarks",
    "covariance_ellipse_params",
    "plot_covariance_ellipse",
    "plot_scan",
    "plot_belief",
]

#: Colour of unknown cells (-1) in :func:`plot_map`: a pale blue, distinct from free (white).
UNKNOWN_COLOR = "#c6d5e6"

#: Points on the unit circle: an Ellipse patch's path before its patch transform.
_UNIT_CIRCLE = np.stack(
    [np.cos(np.linspace(0, 2 * np.pi, 65)), np.sin(np.linspace(0, 2 * np.pi, 65))], -1
)


def plot_map(
    grid: OccupancyGrid,
    ax: Axes | None = None,
    *,
    title: str | None = None,
    unknown_color: str = UNKNOWN_COLOR,
    cmap: str | Colormap = "gray_r",
    **imshow_kw,
) -> Axes:
    """Draw an occupancy grid in world coordinates.

    Cells are drawn with ``origin='lower'`` (row 0 at the bottom, as stored in
    :class:`~robolab.maps.OccupancyGrid`) over the grid's extent in metres, so
    poses and scans in the map frame overlay it directly. Occupancy 0 (free) is
    white and 1 (occupied) black with the default ``'gray_r'`` colormap;
    unknown cells (-1) get ``unknown_color``. A map whose origin has a yaw is
    rotated about its origin.

    Parameters
    ----------
    grid : OccupancyGrid
        The map.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    title : str, optional
        Axes title (default "Occupancy grid" for a new figure).
    unknown_color : matplotlib colour
        Colour of unknown cells.
    cmap : str or Colormap
        Colormap for occupancy in [0, 1].
    **imshow_kw
        Passed to :meth:`~matplotlib.axes.Axes.imshow` (e.g. ``alpha``).

    Returns
    -------
    matplotlib.axes.Axes
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    ax = _axes(ax, "Occupancy grid", title)
    cm = plt.get_cmap(cmap).with_extremes(bad=unknown_color)
    shown = np.ma.masked_where(grid.data == UNKNOWN, grid.data)
    image = ax.imshow(
        shown,
        origin="lower",
        extent=grid.extent,
        cmap=cm,
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
        **imshow_kw,
    )
    yaw = float(grid.origin[2])
    if yaw != 0.0:
        x0, y0 = grid.origin[:2]
        image.set_transform(Affine2D().rotate_around(x0, y0, yaw) + ax.transData)
        corners = grid.cell_to_world(
            np.array([[0, 0], [0, 1], [1, 0], [1, 1]]) * np.array(grid.shape) - 0.5
        )
        ax.update_datalim(corners)
        ax.autoscale_view()
    if not ax.get_xlabel():
        ax.set_xlabel("x [m]")
    if not ax.get_ylabel():
        ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    return ax


def plot_poses(
    poses,
    ax: Axes | None = None,
    *,
    title: str | None = None,
    color=None,
    label: str | None = None,
    path: bool = True,
    arrows: bool = True,
    arrow_every: int | None = None,
    arrow_length: float | None = None,
    linestyle: str = "-",
    linewidth: float = 1.5,
) -> Axes:
    """Draw a sequence of poses: the path through them plus heading arrows.

    Parameters
    ----------
    poses : array_like, shape (3,) or (N, 3)
        Poses ``(x, y, theta)`` in metres and radians.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    title : str, optional
        Axes title (default "Poses" for a new figure).
    color : matplotlib colour, optional
        One colour for the path and the arrows (the next in the cycle by default).
    label : str, optional
        Legend label for the path.
    path : bool
        Draw the line through the positions.
    arrows : bool
        Draw heading arrows.
    arrow_every : int, optional
        Draw an arrow at every ``arrow_every``-th pose (and the last); by
        default about 20 arrows in all.
    arrow_length : float, optional
        Arrow length in metres; by default 5 % of the path's larger extent
        (0.5 m for a single pose or a path that stays in place).
    linestyle, linewidth
        Style of the path.

    Returns
    -------
    matplotlib.axes.Axes
    """
    p = as_poses("poses", poses)
    ax = _axes(ax, "Poses", title)
    if path:
        (line,) = ax.plot(
            p[:, 0], p[:, 1], linestyle=linestyle, linewidth=linewidth, color=color, label=label
        )
        color = line.get_color()
    elif color is None:
        color = "tab:blue"
    if arrows:
        n = len(p)
        step = max(1, n // 20) if arrow_every is None else int(arrow_every)
        if step < 1:
            raise ValueError(f"arrow_every must be a positive integer, got {arrow_every!r}")
        idx = np.unique(np.r_[np.arange(0, n, step), n - 1])
        if arrow_length is None:
            span = float(np.ptp(p[:, :2], axis=0).max())
            arrow_length = 0.05 * span if span > 0 else 0.5
        length = check_positive("arrow_length", arrow_length)
        q = p[idx]
        ax.quiver(
            q[:, 0],
            q[:, 1],
            length * np.cos(q[:, 2]),
            length * np.sin(q[:, 2]),
            color=color,
            angles="xy",
            scale_units="xy",
            scale=1.0,
            width=0.004,
            label=None if path else label,
        )
    ax.set_aspect("equal", adjustable="datalim")
    return ax


def plot_particles(
    particles,
    weights=None,
    ax: Axes | None = None,
    *,
    title: str | None = None,
    color="tab:red",
    size: float = 6.0,
    headings: bool = False,
    label: str | None = "particles",
    alpha: float = 0.6,
) -> Axes:
    """Scatter a particle set; marker area proportional to the weight when weights are given.

    Parameters
    ----------
    particles : array_like, shape (M, 2) or (M, 3)
        Particle positions (and headings) in metres and radians.
    weights : array_like, shape (M,), optional
        Non-negative importance weights (need not be normalized). The marker
        area is ``size * M * w / sum(w)``, so uniform weights give ``size``.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    title : str, optional
        Axes title (default "Particles" for a new figure).
    color : matplotlib colour
    size : float
        Marker area in points^2 for a particle of average weight.
    headings : bool
        Also draw a short arrow per particle (needs ``(M, 3)``).
    label : str, optional
        Legend label.
    alpha : float
        Marker opacity.

    Returns
    -------
    matplotlib.axes.Axes
    """
    p = as_array("particles", particles, ndim=2, finite=True)
    if p.shape[1] not in (2, 3):
        raise ValueError(f"particles must have shape (M, 2) or (M, 3), got {p.shape}")
    sizes = np.full(len(p), float(size))
    if weights is not None:
        w = as_array("weights", weights, shape=(len(p),), finite=True, nonnegative=True)
        total = w.sum()
        if total <= 0:
            raise ValueError("weights must not all be zero")
        sizes = size * len(p) * w / total
    ax = _axes(ax, "Particles", title)
    ax.scatter(p[:, 0], p[:, 1], s=sizes, c=color, alpha=alpha, linewidths=0, label=label)
    if headings:
        if p.shape[1] != 3:
            raise ValueError("headings=True needs particles of shape (M, 3)")
        span = float(np.ptp(p[:, :2], axis=0).max()) if len(p) > 1 else 0.0
        length = 0.03 * span if span > 0 else 0.2
        ax.quiver(
            p[:, 0],
            p[:, 1],
            length * np.cos(p[:, 2]),
            length * np.sin(p[:, 2]),
            color=color,
            alpha=alpha,
            angles="xy",
            scale_units="xy",
            scale=1.0,
            width=0.002,
        )
    ax.set_aspect("equal", adjustable="datalim")
    return ax


def plot_landmarks(
    landmarks,
    ax: Axes | None = None,
    labels: Sequence[str] | bool | None = None,
    *,
    title: str | None = None,
    color="tab:blue",
    marker: str = "*",
    size: float = 150.0,
    label: str | None = "landmarks",
) -> Axes:
    """Mark landmark positions, optionally annotated.

    Parameters
    ----------
    landmarks : array_like, shape (K, 2)
        Landmark positions in metres.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    labels : sequence of str or True, optional
        One text per landmark, or ``True`` for their indices ``0 .. K-1``.
    title : str, optional
        Axes title (default "Landmarks" for a new figure).
    color, marker, size
        Marker style (``size`` in points^2).
    label : str, optional
        Legend label.

    Returns
    -------
    matplotlib.axes.Axes
    """
    lm = as_array("landmarks", landmarks, ndim=(1, 2), finite=True)
    if lm.ndim == 1:
        lm = lm[None, :]
    if lm.shape[1] != 2:
        raise ValueError(f"landmarks must have shape (K, 2), got {lm.shape}")
    if labels is True:
        texts = [str(i) for i in range(len(lm))]
    elif labels is None or labels is False:
        texts = []
    else:
        texts = [str(t) for t in labels]
        if len(texts) != len(lm):
            raise ValueError(
                f"labels must have one entry per landmark ({len(lm)}), got {len(texts)}"
            )
    ax = _axes(ax, "Landmarks", title)
    ax.scatter(lm[:, 0], lm[:, 1], s=size, c=color, marker=marker, label=label, zorder=3)
    for (x, y), text in zip(lm, texts, strict=False):
        ax.annotate(text, (x, y), xytext=(6, 6), textcoords="offset points", color=color)
    ax.set_aspect("equal", adjustable="datalim")
    return ax


def covariance_ellipse_params(cov, n_std: float = 2.0):
    r"""Width, height and angle of the ``n_std``-sigma ellipse of 2 x 2 covariances.

    With the eigen-decomposition :math:`\Sigma = V \operatorname{diag}(\lambda_1,
    \lambda_2) V^T`, :math:`\lambda_1 \ge \lambda_2`, the points at Mahalanobis
    distance ``n_std`` from the mean,
    :math:`(x - \mu)^T \Sigma^{-1} (x - \mu) = n^2`, form an ellipse with
    semi-axes :math:`n \sqrt{\lambda_1}` and :math:`n \sqrt{\lambda_2}`, the
    major one along the eigenvector :math:`v_1` (see Probabilistic Robotics,
    section 3.2, Gaussians).

    Parameters
    ----------
    cov : array_like, shape (2, 2) or (K, 2, 2)
        Symmetric positive semi-definite covariances, metres^2.
    n_std : float
        Number of standard deviations (Mahalanobis radius).

    Returns
    -------
    width, height, angle : float or ndarray of shape (K,)
        Full axis lengths ``2 n sqrt(lambda)`` (major first) and the angle of
        the major axis in degrees, counter-clockwise from x, in (-90, 90].

    Raises
    ------
    ValueError
        When ``cov`` is not a (stack of) symmetric positive semi-definite 2 x 2 matrices.
    """
    c = as_array("cov", cov, ndim=(2, 3), finite=True)
    if c.shape[-2:] != (2, 2):
        raise ValueError(f"cov must have shape (2, 2) or (K, 2, 2), got {c.shape}")
    n = check_positive("n_std", n_std)
    scale = np.maximum(np.abs(c).max(axis=(-2, -1)), np.finfo(float).tiny)
    if np.any(np.abs(c[..., 0, 1] - c[..., 1, 0]) > 1e-9 * scale):
        raise ValueError("cov must be symmetric")
    lam, vec = np.linalg.eigh(c)  # ascending eigenvalues
    if np.any(lam[..., 0] < -1e-9 * scale):
        raise ValueError(f"cov must be positive semi-definite, got eigenvalues {lam.min():.3g} < 0")
    lam = np.clip(lam, 0.0, None)
    major = vec[..., :, 1]
    angle = np.degrees(np.arctan2(major[..., 1], major[..., 0]))
    angle = np.where(angle <= -90.0, angle + 180.0, np.where(angle > 90.0, angle - 180.0, angle))
    width = 2.0 * n * np.sqrt(lam[..., 1])
    height = 2.0 * n * np.sqrt(lam[..., 0])
    if c.ndim == 2:
        return float(width), float(height), float(angle)
    return width, height, angle


def plot_covariance_ellipse(
    mean, cov, ax: Axes | None = None, n_std: float = 2.0, *, title: str | None = None, **kw
):
    r"""Draw the ``n_std``-sigma ellipse of a 2D Gaussian (or of many at once).

    The ellipse is :math:`\{x : (x - \mu)^T \Sigma^{-1} (x - \mu) = n^2\}`; its
    semi-axes are :math:`n \sqrt{\lambda_i}` along the eigenvectors of
    :math:`\Sigma` (see :func:`covariance_ellipse_params`). For a pose
    covariance pass the position block ``cov[:2, :2]``.

    Parameters
    ----------
    mean : array_like, shape (2,) or (K, 2)
        Centre(s) in metres.
    cov : array_like, shape (2, 2) or (K, 2, 2)
        Covariance(s) in metres^2.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    n_std : float
        Mahalanobis radius (2 encloses about 86 % of a 2D Gaussian's mass).
    title : str, optional
        Axes title (default "Covariance ellipse" for a new figure).
    **kw
        Patch properties (``edgecolor``, ``facecolor``, ``linewidth``, ``label`` ...);
        by default an unfilled outline.

    Returns
    -------
    matplotlib.patches.Ellipse or matplotlib.collections.EllipseCollection
        One patch for a single Gaussian, one collection for a stack of them.
    """
    m = as_array("mean", mean, ndim=(1, 2), finite=True)
    if m.shape[-1] != 2:
        raise ValueError(f"mean must have shape (2,) or (K, 2), got {m.shape}")
    width, height, angle = covariance_ellipse_params(cov, n_std)
    c_ndim = np.ndim(width) + 2
    if m.ndim + 1 != c_ndim or (m.ndim == 2 and len(m) != len(np.atleast_1d(width))):
        raise ValueError(
            f"mean {m.shape} and cov {np.shape(cov)} must describe the same number of Gaussians"
        )
    ax = _axes(ax, "Covariance ellipse", title)
    kw.setdefault("facecolor", "none")
    kw.setdefault("edgecolor", kw.pop("color", "tab:purple"))
    if m.ndim == 1:
        artist = Ellipse(tuple(m), width, height, angle=angle, **kw)
        ax.add_patch(artist)
        xy = artist.get_patch_transform().transform(_UNIT_CIRCLE)
    else:
        artist = EllipseCollection(
            width, height, angle, units="xy", offsets=m, offset_transform=ax.transData, **kw
        )
        ax.add_collection(artist)
        r = np.maximum(width, height)[:, None] / 2.0
        xy = np.concatenate([m - r, m + r])
    ax.update_datalim(xy)
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    return artist


def plot_scan(
    scan,
    ax: Axes | None = None,
    origin=None,
    *,
    title: str | None = None,
    color="tab:green",
    size: float = 4.0,
    rays: bool = False,
    max_range: float | None = None,
    label: str | None = "scan",
) -> Axes:
    """Draw a range scan as endpoints (optionally with the beams), placed at a sensor pose.

    Parameters
    ----------
    scan : array_like (P, 2), or tuple (ranges, angles)
        Endpoints in the sensor frame, or ranges (metres) and beam angles
        (radians, counter-clockwise from the sensor's x axis). Returns that are
        not finite, not positive, or at/above ``max_range`` are dropped (a
        LaserScan's "no return"), never drawn as hits.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    origin : array_like (3,), optional
        The sensor's pose ``(x, y, theta)`` in the plotted frame; the identity
        by default. Endpoints are mapped with
        :func:`robolab.geometry.transform_points`.
    title : str, optional
        Axes title (default "Laser scan" for a new figure).
    color, size
        Marker colour and area (points^2).
    rays : bool
        Also draw the beam from the sensor to each endpoint.
    max_range : float, optional
        Drop returns ``>= max_range`` (only with ranges and angles).
    label : str, optional
        Legend label.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if isinstance(scan, tuple) and len(scan) == 2:
        ranges = as_array("ranges", scan[0], ndim=1)
        angles = as_array("angles", scan[1], shape=(len(ranges),), finite=True)
        valid = np.isfinite(ranges) & (ranges > 0)
        if max_range is not None:
            valid &= ranges < check_positive("max_range", max_range)
        r, a = ranges[valid], angles[valid]
        pts = np.stack([r * np.cos(a), r * np.sin(a)], -1)
    else:
        pts = as_array("scan", scan, ndim=2)
        if pts.shape[1] != 2:
            raise ValueError(
                "scan must be points of shape (P, 2) or a tuple (ranges, angles), "
                f"got shape {pts.shape}"
            )
        pts = pts[np.all(np.isfinite(pts), axis=1)]
    pose = np.zeros(3) if origin is None else as_array("origin", origin, shape=(3,), finite=True)
    world = transform_points(pts, pose)
    ax = _axes(ax, "Laser scan", title)
    if rays and len(world):
        segs = np.stack([np.broadcast_to(pose[:2], world.shape), world], 1)
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(segs, colors=color, linewidths=0.5, alpha=0.3))
    ax.scatter(world[:, 0], world[:, 1], s=size, c=color, linewidths=0, label=label)
    ax.plot(pose[0], pose[1], marker="o", color="k", markersize=4)
    ax.set_aspect("equal", adjustable="datalim")
    return ax


def plot_belief(
    belief,
    positions=None,
    ax: Axes | None = None,
    *,
    title: str | None = None,
    xlabel: str = "x [m]",
    ylabel: str = "belief bel(x)",
    color="tab:blue",
    width: float | None = None,
    label: str | None = None,
    tick_labels: Sequence[str] | None = None,
) -> Axes:
    """Bar chart of a discrete belief (a histogram filter's state).

    Parameters
    ----------
    belief : array_like, shape (n,)
        Probabilities of the n states (non-negative; drawn as given).
    positions : array_like, shape (n,), optional
        Where each state lies on the x axis (e.g. cell centres in metres);
        ``0 .. n-1`` by default.
    ax : Axes, optional
        Where to draw; a new figure (not equal-aspect) when omitted.
    title : str, optional
        Axes title (default "Belief" for a new figure).
    xlabel, ylabel : str
        Axis labels for a new figure.
    color, width, label
        Bar style; ``width`` defaults to 80 % of the spacing between states.
    tick_labels : sequence of str, optional
        Names of the states (e.g. ``["open", "closed"]``) as x tick labels.

    Returns
    -------
    matplotlib.axes.Axes
    """
    b = as_array("belief", belief, ndim=1, finite=True, nonnegative=True)
    x = (
        np.arange(len(b), dtype=float)
        if positions is None
        else as_array("positions", positions, shape=(len(b),), finite=True)
    )
    if width is None:
        width = 0.8 * (float(np.min(np.diff(np.sort(x)))) if len(x) > 1 else 1.0)
    ax = _axes(ax, "Belief", title, xlabel=xlabel, ylabel=ylabel, equal=False)
    ax.bar(x, b, width=width, color=color, label=label)
    if tick_labels is not None:
        if len(tick_labels) != len(b):
            raise ValueError(
                f"tick_labels must have one entry per state ({len(b)}), got {len(tick_labels)}"
            )
        ax.set_xticks(x, [str(t) for t in tick_labels])
    ax.set_ylim(bottom=0.0)
    return ax
