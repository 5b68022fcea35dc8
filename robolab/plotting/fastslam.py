"""Figures of lab 07, FastSLAM with the fiducial robot.

Built on :mod:`robolab.plotting.core`; every function takes an optional Axes,
makes a titled, labelled one when omitted, and returns it.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D

from robolab.plotting.core import (
    new_axes,
    panel_grid,
    plot_covariance_ellipse,
    plot_landmarks,
    plot_poses,
)
from robolab.validation import as_array

__all__ = [
    "plot_fastslam_map",
    "plot_landmark_zooms",
    "plot_particle_maps",
    "plot_error_vs_particles",
    "plot_errors_over_time",
]


def plot_fastslam_map(
    true_poses,
    fiducials,
    path,
    landmarks,
    landmark_covs,
    ax: Axes | None = None,
    *,
    n_std: float = 2.0,
    title: str = "FastSLAM: estimated and true fiducials and paths",
    dead_reckoning=None,
) -> Axes:
    """The lab's summary figure: true and estimated fiducials (with covariance ellipses) and paths.

    Parameters
    ----------
    true_poses : array_like (T+1, 3)
        Ground-truth path.
    fiducials : array_like (K, 2)
        True fiducial positions.
    path : array_like (T+1, 3)
        Estimated path.
    landmarks : array_like (K, 2)
        Estimated fiducial positions; NaN rows (never observed) are skipped.
    landmark_covs : array_like (K, 2, 2)
        Their covariances, drawn as ``n_std``-sigma ellipses.
    ax : Axes, optional
    n_std : float
        Mahalanobis radius of the ellipses.
    title : str
    dead_reckoning : array_like (T+1, 3), optional
        The commands integrated without correction, for comparison.
    """
    fid = as_array("fiducials", fiducials, ndim=2)
    lm = as_array("landmarks", landmarks, ndim=2)
    covs = as_array("landmark_covs", landmark_covs, ndim=3)
    if lm.shape != fid.shape or covs.shape != (len(lm), 2, 2):
        raise ValueError(
            f"landmarks {lm.shape} and landmark_covs {covs.shape} must match fiducials {fid.shape}"
        )
    ax = new_axes(title, figsize=(7.5, 6.5)) if ax is None else ax
    if ax.get_title() == "":
        ax.set_title(title)
    plot_poses(true_poses, ax, color="black", label="true path", arrows=False, linewidth=1.2)
    plot_poses(
        path,
        ax,
        color="tab:orange",
        label="FastSLAM path",
        arrows=False,
        linestyle="--",
        linewidth=1.2,
    )
    if dead_reckoning is not None:
        plot_poses(
            dead_reckoning,
            ax,
            color="tab:gray",
            label="dead reckoning",
            arrows=False,
            linestyle=":",
        )
    plot_landmarks(
        fid, ax, labels=True, color="black", label="true fiducials", marker="*", size=160
    )
    ok = np.all(np.isfinite(lm), axis=1)
    if ok.any():
        ax.scatter(
            lm[ok, 0],
            lm[ok, 1],
            marker="x",
            s=60,
            color="tab:red",
            label="estimated fiducials",
            zorder=4,
        )
        for mean, cov in zip(lm[ok], covs[ok], strict=True):
            plot_covariance_ellipse(mean, cov, ax, n_std=n_std, edgecolor="tab:red", linewidth=1.2)
        handles, labels = ax.get_legend_handles_labels()
        handles.append(Line2D([], [], color="tab:red", linewidth=1.2))
        labels.append(f"{n_std:g}-sigma ellipses")
        ax.legend(handles, labels, loc="best", fontsize="small")
    else:
        ax.legend(loc="best", fontsize="small")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return ax


def plot_landmark_zooms(
    fiducials,
    landmarks,
    landmark_covs,
    particle_means=None,
    *,
    half_width: float = 0.5,
    n_std: float = 2.0,
    title: str = "Each fiducial up close: estimate, 2-sigma ellipse, truth",
):
    """One small panel per fiducial, centred on the true position, ``half_width`` metres each way.

    Draws the true fiducial, the estimate with its ``n_std``-sigma ellipse and, when
    ``particle_means`` (M, K, 2) is given, every particle's mean of that landmark.
    Returns the array of Axes.
    """
    fid = as_array("fiducials", fiducials, ndim=2)
    lm = as_array("landmarks", landmarks, ndim=2)
    covs = as_array("landmark_covs", landmark_covs, ndim=3)
    k = len(fid)
    fig, axes = panel_grid(k, panel=(3.6, 3.4), max_cols=3, title=title)
    for j, ax in enumerate(axes):
        ax.set_title(f"fiducial {j}")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if particle_means is not None:
            pm = np.asarray(particle_means, dtype=float)[:, j]
            ax.scatter(
                pm[:, 0], pm[:, 1], s=6, color="tab:blue", alpha=0.4, label="particles' means"
            )
        ax.scatter(*fid[j], marker="*", s=160, color="black", label="true", zorder=3)
        if np.all(np.isfinite(lm[j])):
            ax.scatter(*lm[j], marker="+", s=40, color="tab:red", label="estimate", zorder=4)
            plot_covariance_ellipse(lm[j], covs[j], ax, n_std=n_std, edgecolor="tab:red")
        ax.set_xlim(fid[j, 0] - half_width, fid[j, 0] + half_width)
        ax.set_ylim(fid[j, 1] - half_width, fid[j, 1] + half_width)
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize="small",
               frameon=False)
    return np.asarray(axes, dtype=object)


def plot_particle_maps(
    means,
    covs,
    particles=(0, 1),
    ax: Axes | None = None,
    *,
    landmarks=None,
    seen=None,
    n_std: float = 2.0,
    title: str = "Each particle carries its own map",
) -> Axes:
    """A few particles' landmark ellipses on top of each other (one EKF per landmark per particle).

    Parameters
    ----------
    means : array_like (M, K, 2)
    covs : array_like (M, K, 2, 2)
    particles : sequence of int
        Which particles to draw, each in its own colour.
    landmarks : sequence of int, optional
        Which landmarks to draw (default all).
    seen : array_like (M, K) of bool, optional
        Skip landmarks a particle has no belief about.
    """
    mu = as_array("means", means, ndim=3)
    sig = as_array("covs", covs, ndim=4)
    ok = np.ones(mu.shape[:2], dtype=bool) if seen is None else np.asarray(seen, dtype=bool)
    js = range(mu.shape[1]) if landmarks is None else [int(j) for j in landmarks]
    ax = new_axes(title) if ax is None else ax
    colors = plt.get_cmap("tab10").colors
    for n, k in enumerate(particles):
        c = colors[n % len(colors)]
        drawn = [j for j in js if ok[k, j]]
        if not drawn:
            continue
        ax.scatter(
            mu[k, drawn, 0], mu[k, drawn, 1], marker="+", s=50, color=c, label=f"particle {k}"
        )
        for j in drawn:
            plot_covariance_ellipse(mu[k, j], sig[k, j], ax, n_std=n_std, edgecolor=c)
    ax.legend(loc="best", fontsize="small")
    return ax


def plot_error_vs_particles(
    n_particles,
    errors,
    ax: Axes | None = None,
    *,
    labels=("landmark RMSE", "final pose error"),
    title: str = "Accuracy against the number of particles M",
) -> Axes:
    """Median and min-max band of errors over repeated runs, against M (log axis).

    Parameters
    ----------
    n_particles : array_like (P,)
        The particle counts.
    errors : array_like (P, R, E)
        ``E`` error measures (metres) for ``R`` runs at each count.
    labels : sequence of str
        One label per error measure.
    """
    m = as_array("n_particles", n_particles, ndim=1)
    err = as_array("errors", errors, ndim=3)
    if err.shape[0] != len(m) or err.shape[2] != len(labels):
        raise ValueError(f"errors must have shape ({len(m)}, runs, {len(labels)}), got {err.shape}")
    ax = (
        new_axes(title, xlabel="number of particles M", ylabel="error [m]", equal=False)
        if ax is None
        else ax
    )
    for e, label in enumerate(labels):
        med = np.median(err[:, :, e], axis=1)
        (line,) = ax.plot(m, med, marker="o", label=f"{label} (median)")
        ax.fill_between(
            m,
            err[:, :, e].min(1),
            err[:, :, e].max(1),
            color=line.get_color(),
            alpha=0.2,
            label=f"{label} (min-max over {err.shape[1]} runs)",
        )
    ax.set_xscale("log")
    ax.set_xticks(m)
    ax.set_xticklabels([f"{int(v)}" for v in m])
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return ax


def plot_errors_over_time(
    t,
    series: dict,
    ax: Axes | None = None,
    *,
    ylabel: str = "error [m]",
    title: str = "Error over time",
    events=None,
) -> Axes:
    """Error curves against time, one per entry of ``series`` (label -> array (T,)).

    ``events`` (optional): times to mark with vertical lines, e.g. loop closures.
    """
    tt = as_array("t", t, ndim=1)
    ax = new_axes(title, xlabel="time [s]", ylabel=ylabel, equal=False) if ax is None else ax
    for label, values in series.items():
        v = as_array(label, values, ndim=1)
        if v.shape != tt.shape:
            raise ValueError(f"series {label!r} must have shape {tt.shape}, got {v.shape}")
        ax.plot(tt, v, label=label)
    for n, e in enumerate(events or ()):
        ax.axvline(
            e,
            color="gray",
            linestyle=":",
            linewidth=1,
            label="event (e.g. loop closed)" if n == 0 else None,
        )
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return ax
