"""Figures for lab 06, EKF localization with grid mapping.

The evidence map (``+1`` per hit, ``-0.2`` per pass, ``0`` never seen)
is drawn with three colours: yellow where the score is positive (obstacle
seen), dark blue where it is negative (free), light blue where no beam has
reached. The map is in the lab's units: one unit per cell, cell ``(row, col)``
covering ``[col, col + 1) x [row, row + 1)``.

Every function draws into ``ax`` when given and otherwise makes a titled,
labelled figure; each returns the Axes it drew on (or an array of Axes).
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.patches import Patch

from robolab.plotting.core import (
    legend_outside,
    new_axes,
    panel_grid,
    plot_covariance_ellipse,
    plot_particles,
)
from robolab.validation import as_array

__all__ = [
    "EVIDENCE_CMAP",
    "EVIDENCE_NORM",
    "plot_evidence_map",
    "plot_map_growth",
    "plot_ekf_path",
    "plot_errors",
    "plot_particle_cloud",
]

#: Free (score < 0), unseen (0), obstacle seen (score > 0): the lab's colours.
EVIDENCE_COLORS = ("#1f2a7a", "#9ecae1", "#f5d218")
EVIDENCE_CMAP = ListedColormap(EVIDENCE_COLORS, name="evidence")
#: Bin edges: (-inf, -eps) free, [-eps, eps] unseen, (eps, inf) seen obstacle.
EVIDENCE_NORM = BoundaryNorm([-1e300, -1e-9, 1e-9, 1e300], EVIDENCE_CMAP.N)
_UNITS = "[units]"


def _evidence(name, value):
    return as_array(name, value, ndim=2, finite=True)


def _axes(ax, title, **kw):
    return new_axes(title, f"x {_UNITS}", f"y {_UNITS}", **kw) if ax is None else ax


def plot_evidence_map(
    evidence,
    ax=None,
    *,
    title="Evidence map (yellow: obstacle, dark blue: free)",
    legend=True,
    truth=None,
):
    """Draw an evidence map in its three colours: free, unseen, obstacle.

    Parameters
    ----------
    evidence : array_like, shape (H, W)
        Accumulated scores, ``evidence[row, col]`` with row = y.
    ax : Axes, optional
    title : str
    legend : bool
        Add a legend naming the three colours.
    truth : array_like, shape (H, W), optional
        The true occupancy (0/1); its obstacle outlines are drawn in black.

    Returns
    -------
    matplotlib.axes.Axes
    """
    m = _evidence("evidence", evidence)
    ax = _axes(ax, title)
    if title:
        ax.set_title(title)
    h, w = m.shape
    ax.imshow(
        m,
        origin="lower",
        extent=(0, w, 0, h),
        cmap=EVIDENCE_CMAP,
        norm=EVIDENCE_NORM,
        interpolation="nearest",
    )
    if truth is not None:
        t = _evidence("truth", truth)
        if t.shape != m.shape:
            raise ValueError(f"truth must have the map's shape {m.shape}, got {t.shape}")
        k = 10  # sub-cells per cell: the contour then follows the cell edges to 1/20 of a cell
        fine = np.kron(t > 0.5, np.ones((k, k)))
        ax.contour(
            (np.arange(w * k) + 0.5) / k,
            (np.arange(h * k) + 0.5) / k,
            fine,
            levels=[0.5],
            colors="k",
            linewidths=0.8,
        )
    ax.set_xlim(0, w)
    ax.set_ylim(0, h)
    ax.set_xlabel(f"x {_UNITS}")
    ax.set_ylabel(f"y {_UNITS}")
    ax.set_aspect("equal", adjustable="box")
    if legend:
        legend_outside(ax, handles=_evidence_handles())
    return ax


def _evidence_handles() -> list[Patch]:
    labels = ("free (< 0)", "unseen (0)", "obstacle (> 0)")
    return [Patch(color=c, label=lab) for c, lab in zip(EVIDENCE_COLORS, labels, strict=True)]


def plot_map_growth(snapshots, times, *, truth=None, paths=None, suptitle="The map as it grows"):
    """One evidence map per snapshot time, side by side.

    Parameters
    ----------
    snapshots : sequence of array_like (H, W)
        Maps at ``times``.
    times : sequence of float
        Seconds, for the panel titles.
    truth : array_like (H, W), optional
        True occupancy, outlined in black.
    paths : sequence of array_like (T_i, 2 or 3), optional
        The estimated path up to each snapshot, drawn in white.
    suptitle : str

    Returns
    -------
    numpy.ndarray of Axes
    """
    snaps = list(snapshots)
    times = list(times)
    if len(snaps) != len(times) or not snaps:
        raise ValueError(
            "snapshots and times must be non-empty and of equal length, "
            f"got {len(snaps)} and {len(times)}"
        )
    fig, axes = panel_grid(len(snaps), panel=(4.4, 4.2))
    for i, (m, t) in enumerate(zip(snaps, times, strict=True)):
        ax = axes[i]
        plot_evidence_map(m, ax, title=f"t = {t:g} s", legend=False, truth=truth)
        if paths is not None:
            p = as_array("paths[i]", paths[i], ndim=2, finite=True)
            ax.plot(p[:, 0], p[:, 1], color="w", lw=1.2)
            ax.plot(p[-1, 0], p[-1, 1], "o", color="w", ms=4)
    fig.suptitle(suptitle)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.legend(handles=_evidence_handles(), loc="lower center", ncol=3, fontsize="small",
               frameon=False)
    return axes[0]


def plot_ekf_path(
    estimates,
    covariances,
    truth,
    ax=None,
    *,
    every=25,
    n_std=2.0,
    evidence=None,
    title="EKF estimate with 2-sigma ellipses against ground truth",
    label="EKF estimate",
):
    """The estimated path with position covariance ellipses, and the true path.

    Parameters
    ----------
    estimates : array_like, shape (T, 3)
        Estimated poses.
    covariances : array_like, shape (T, 3, 3)
        Their covariances; the position block ``[:2, :2]`` is drawn.
    truth : array_like, shape (T, 2 or 3)
        True poses at the same steps.
    ax : Axes, optional
    every : int
        Draw an ellipse every ``every`` steps.
    n_std : float
        Mahalanobis radius of the ellipses.
    evidence : array_like (H, W), optional
        Evidence map drawn underneath.
    title, label : str

    Returns
    -------
    matplotlib.axes.Axes
    """
    est = as_array("estimates", estimates, ndim=2, finite=True)
    cov = as_array("covariances", covariances, ndim=3, finite=True)
    tru = as_array("truth", truth, ndim=2, finite=True)
    if len(est) != len(cov) or len(est) != len(tru):
        raise ValueError(
            f"estimates, covariances and truth must have the same length, got "
            f"{len(est)}, {len(cov)}, {len(tru)}"
        )
    ax = _axes(ax, title)
    ax.set_title(title)
    if evidence is not None:
        plot_evidence_map(evidence, ax, title=title, legend=False)
    ax.plot(tru[:, 0], tru[:, 1], color="k", lw=1.5, ls="--", label="ground truth")
    ax.plot(est[:, 0], est[:, 1], color="tab:red", lw=1.5, label=label)
    idx = np.arange(0, len(est), max(int(every), 1))
    plot_covariance_ellipse(
        est[idx, :2], cov[idx, :2, :2], ax, n_std=n_std, edgecolor="tab:red", linewidth=1.0
    )
    ax.set_xlabel(f"x {_UNITS}")
    ax.set_ylabel(f"y {_UNITS}")
    handles, _ = ax.get_legend_handles_labels()
    handles.append(
        Patch(facecolor="none", edgecolor="tab:red", label=f"{n_std:g}-sigma position ellipse")
    )
    legend_outside(ax, handles=handles)
    ax.set_aspect("equal", adjustable="box")
    return ax


def plot_errors(
    t,
    errors,
    ax=None,
    *,
    ylabel=f"position error {_UNITS}",
    title="Position error over time",
    log=False,
):
    """Error curves of several filters on one time axis.

    Parameters
    ----------
    t : array_like, shape (T,)
        Time in seconds.
    errors : dict of str -> array_like (T,)
        Label -> error at each time.
    ax : Axes, optional
    ylabel, title : str
    log : bool
        Logarithmic y axis.

    Returns
    -------
    matplotlib.axes.Axes
    """
    t = as_array("t", t, ndim=1, finite=True)
    if ax is None:
        ax = new_axes(title, "time [s]", ylabel, equal=False, figsize=(7.0, 3.8))
    for name, e in errors.items():
        e = as_array(f"errors[{name!r}]", e, shape=(len(t),))
        ax.plot(t, e, label=name)
    if log:
        ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_particle_cloud(
    particles, truth, world, ax=None, *, estimate=None, title="Particle filter"
):
    """Particles over the true world, with the true pose (and an estimate).

    Parameters
    ----------
    particles : array_like, shape (M, 3)
    truth : array_like, shape (3,)
    world : array_like, shape (H, W)
        True occupancy 0/1 (unit cells).
    ax : Axes, optional
    estimate : array_like, shape (3,), optional
    title : str

    Returns
    -------
    matplotlib.axes.Axes
    """
    w = _evidence("world", world)
    ax = _axes(ax, title)
    ax.set_title(title)
    ax.imshow(
        w,
        origin="lower",
        extent=(0, w.shape[1], 0, w.shape[0]),
        cmap="gray_r",
        vmin=0,
        vmax=1.5,
        interpolation="nearest",
    )
    plot_particles(particles, ax=ax, size=6, alpha=0.5, color="tab:blue", label="particles")
    ax.set_aspect("equal", adjustable="box")
    tr = as_array("truth", truth, shape=(3,))
    ax.plot(tr[0], tr[1], "k*", ms=12, label="true pose")
    if estimate is not None:
        e = as_array("estimate", estimate, shape=(3,))
        ax.plot(e[0], e[1], "rx", ms=10, mew=2, label="estimate")
    ax.set_xlim(0, w.shape[1])
    ax.set_ylim(0, w.shape[0])
    ax.set_xlabel(f"x {_UNITS}")
    ax.set_ylabel(f"y {_UNITS}")
    legend_outside(ax)
    return ax
