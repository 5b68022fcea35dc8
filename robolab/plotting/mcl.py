"""Figures for lab 05, Monte Carlo localization; its runners are re-exported from
:mod:`robolab.plotting.mcl_runs` (data loading and the filter runs the figures show).

* figures: :func:`plot_likelihood_field`, :func:`plot_snapshots`,
  :func:`plot_errors`, :func:`plot_particle_count`;
* runners: :func:`load_localization`, :func:`run_mcl`, :func:`run_augmented`,
  :func:`run_kld`, :func:`estimate_pose` (see :mod:`robolab.plotting.mcl_runs`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes

from robolab.maps import OccupancyGrid
from robolab.plotting.core import legend_outside, new_axes, panel_grid, plot_map
from robolab.plotting.mcl_runs import (
    SNAPSHOT_TIMES,
    LocalizationData,
    convergence_time,
    estimate_pose,
    kld_resample,
    load_localization,
    pose_errors,
    run_augmented,
    run_kld,
    run_mcl,
)

__all__ = [
    "SNAPSHOT_TIMES",
    "LocalizationData",
    "load_localization",
    "estimate_pose",
    "pose_errors",
    "convergence_time",
    "run_mcl",
    "run_augmented",
    "kld_resample",
    "run_kld",
    "plot_likelihood_field",
    "plot_snapshots",
    "plot_errors",
    "plot_particle_count",
]
# ----------------------------------------------------------------------------------------------
# figures
# ----------------------------------------------------------------------------------------------
def plot_likelihood_field(field: dict, ax: Axes | None = None, *, title: str | None = None) -> Axes:
    """The likelihood field in log space, ``log p_hit(d(x, y))``."""
    dist = np.asarray(field["distance"], dtype=float)
    sigma = float(field["sigma_hit"])
    log_p = -0.5 * (dist / sigma) ** 2 - np.log(np.sqrt(2 * np.pi) * sigma)
    res = float(field["resolution"])
    x0, y0 = np.asarray(field["origin"], dtype=float)[:2]
    ax = ax or new_axes(title or "Likelihood field in log space", figsize=(9, 5))
    if title:
        ax.set_title(title)
    im = ax.imshow(
        log_p,
        origin="lower",
        cmap="viridis",
        interpolation="nearest",
        extent=(x0, x0 + dist.shape[1] * res, y0, y0 + dist.shape[0] * res),
    )
    ax.figure.colorbar(
        im, ax=ax, label=r"$\log \mathcal{N}(d; 0, \sigma_{hit}^2)$  [log(1/m)]", shrink=0.8
    )
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return ax


def plot_snapshots(
    grid: OccupancyGrid,
    result: dict,
    truth_at: Callable | None = None,
    *,
    title: str = "MCL",
    max_points: int = 3000,
    times: Sequence[float] | None = None,
) -> plt.Figure:
    """Particles at each snapshot time, true pose and estimate marked.

    ``result`` is from :func:`run_mcl`; the true pose at a snapshot is the
    ground truth of the scan it was taken at. ``times`` picks the snapshots to
    show (default all; a run recorded for an animation has many).
    """
    if times is None:
        times = sorted(result["snapshots"])
    else:
        missing = [t for t in times if t not in result["snapshots"]]
        if missing:
            raise ValueError(f"no snapshot at {missing}; the run has {sorted(result['snapshots'])}")
        times = sorted(times)
    fig, axes = panel_grid(len(times), panel=(4.3, 3.2), title=title)
    for ax, t in zip(axes, times, strict=True):
        p, w = result["snapshots"][t]
        plot_map(grid, ax, title=f"t = {t:g} s")
        show = p if len(p) <= max_points else p[np.linspace(0, len(p) - 1, max_points).astype(int)]
        ax.scatter(
            show[:, 0],
            show[:, 1],
            s=4,
            c="tab:red",
            alpha=0.5,
            linewidths=0,
            label="particles",
            zorder=3,
        )
        k = int(np.argmin(np.abs(result["t"] - t)))
        truth, est = result["truth"][k], result["estimate"][k]
        for pose, color, name in ((truth, "tab:green", "true pose"), (est, "tab:blue", "estimate")):
            ax.plot(
                pose[0], pose[1], "o", mfc="none", mec=color, mew=1.5, ms=9, label=name, zorder=4
            )
            ax.arrow(
                pose[0],
                pose[1],
                0.9 * np.cos(pose[2]),
                0.9 * np.sin(pose[2]),
                color=color,
                width=0.06,
                length_includes_head=True,
                zorder=4,
            )
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels),
               fontsize="small", frameon=False)
    return fig


def plot_errors(
    results: dict, *, title: str = "Localization error against time", skip: float | None = None
):
    """Position and heading error against time, one line per run (``{label: result}``)."""
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for label, r in results.items():
        a1.plot(r["t"], r["position_error"], label=label)
        a2.plot(r["t"], np.rad2deg(r["heading_error"]), label=label)
    if skip is not None:
        for a in (a1, a2):
            a.axvline(skip, color="gray", ls=":", lw=1)
    a1.set_ylabel("position error [m]")
    a2.set_ylabel("heading error [deg]")
    a2.set_xlabel("time [s]")
    a1.set_yscale("log")
    a2.set_yscale("log")
    a1.set_ylim(1e-3, None)
    a2.set_ylim(1e-2, None)
    legend_outside(a1)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_particle_count(result: dict, *, title: str = "Particle count with KLD-sampling"):
    """Number of particles and position error against time (:func:`run_kld`)."""
    ax = new_axes(title, "time [s]", "particles", equal=False, figsize=(9, 3.5))
    ax.plot(result["t"], result["n_particles"], color="tab:purple", label="particles")
    ax.set_yscale("log")
    ax2 = ax.twinx()
    ax2.plot(
        result["t"], result["position_error"], color="tab:orange", lw=1, label="position error"
    )
    ax2.set_ylabel("position error [m]")
    ax2.set_yscale("log")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], loc="upper left",
              bbox_to_anchor=(1.12, 1.0), borderaxespad=0.0, fontsize="small")
    ax.figure.tight_layout()
    return ax
