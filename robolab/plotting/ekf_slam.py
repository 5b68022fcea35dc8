"""Figures of lab 08, EKF-SLAM: maps with covariance ellipses, the correlation matrix, errors.

Built on :mod:`robolab.plotting.core`; every function makes titled, labelled
axes (units in brackets) and returns them.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D

from robolab.plotting.core import (
    legend_outside,
    new_axes,
    panel_grid,
    plot_covariance_ellipse,
    plot_landmarks,
    plot_poses,
)
from robolab.validation import as_array

__all__ = [
    "correlation_matrix",
    "state_labels",
    "plot_ekf_slam_snapshots",
    "plot_correlation_snapshots",
    "plot_pose_errors",
    "plot_entries_changed",
]


def correlation_matrix(sigma) -> np.ndarray:
    r"""Correlation coefficients :math:`\rho_{ab} = \Sigma_{ab} / \sqrt{\Sigma_{aa}\Sigma_{bb}}`.

    Entries with a zero variance (a landmark not in the map yet, a pose known
    exactly) are NaN: they have no correlation.
    """
    s = as_array("sigma", sigma, ndim=2)
    if s.shape[0] != s.shape[1]:
        raise ValueError(f"sigma must be square, got {s.shape}")
    sd = np.sqrt(np.clip(np.diag(s), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = s / np.outer(sd, sd)
    rho[(sd == 0)[:, None] | (sd == 0)[None, :]] = np.nan
    return np.clip(rho, -1.0, 1.0)


def state_labels(n_landmarks: int) -> list[str]:
    """Names of the state's entries: ``x, y, theta, m0x, m0y, ...``."""
    return ["x", "y", "θ"] + [f"m{j}{c}" for j in range(n_landmarks) for c in "xy"]


def plot_ekf_slam_snapshots(
    means,
    covs,
    steps,
    dt: float,
    true_poses,
    landmarks_true,
    *,
    n_std: float = 2.0,
    title: str = "EKF-SLAM: the map and its 2-sigma ellipses over time",
    unit: str = "s",
):
    """Panels of the map at chosen steps: path so far, landmark and pose ellipses, truth.

    Parameters
    ----------
    means : array_like, shape (T + 1, 3 + 2K)
    covs : array_like, shape (T + 1, 3 + 2K, 3 + 2K)
    steps : sequence of int
        Steps to draw (one panel each).
    dt : float
        Time per step, in ``unit`` (for the panel titles).
    true_poses : array_like, shape (T + 1, 3), or None
        Ground truth, drawn up to each step when given.
    landmarks_true : array_like, shape (K, 2)
    unit : str
        The unit of time in the panel titles (``"s"``, or ``"steps"`` with ``dt = 1``).
    """
    mu = as_array("means", means, ndim=2)
    sig = as_array("covs", covs, ndim=3)
    truth = as_array("landmarks_true", landmarks_true, ndim=2)
    k = (mu.shape[1] - 3) // 2
    fig, axes = panel_grid(len(steps), panel=(4.3, 4.0), title=title)
    pad = 1.0
    every = np.vstack([truth, mu[:, :2]])
    lo, hi = np.nanmin(every, axis=0) - pad, np.nanmax(every, axis=0) + pad
    for ax, t in zip(axes, steps, strict=True):
        if true_poses is not None:
            plot_poses(np.asarray(true_poses)[: t + 1], ax, color="black", arrows=False,
                       linewidth=0.8, label="true path")
        plot_poses(mu[: t + 1, :3], ax, color="tab:orange", arrows=False, linestyle="--",
                   linewidth=1.0, label="estimated path")
        plot_landmarks(truth, ax, color="black", marker="*", size=90, label="true landmarks")
        var = np.diagonal(sig[t])[3:].reshape(k, 2)
        in_map = var.sum(axis=1) > 0
        lm = mu[t, 3:].reshape(k, 2)[in_map]
        idx = 3 + 2 * np.flatnonzero(in_map)[:, None] + np.arange(2)
        lm_cov = sig[t][idx[:, :, None], idx[:, None, :]]
        if len(lm):
            ax.scatter(lm[:, 0], lm[:, 1], marker="x", s=40, color="tab:red", zorder=4,
                       label="estimated landmarks")
            plot_covariance_ellipse(lm, lm_cov, ax, n_std=n_std, edgecolor="tab:red",
                                    linewidth=1.0)
        plot_covariance_ellipse(mu[t, :2], sig[t][:2, :2], ax, n_std=n_std,
                                edgecolor="tab:blue", linewidth=1.0)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(f"after {t * dt:g} {unit} ({int(in_map.sum())} of {k} landmarks)",
                     fontsize="medium")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    handles, labels = axes[0].get_legend_handles_labels()
    handles += [Line2D([], [], color="tab:red", linewidth=1.0),
                Line2D([], [], color="tab:blue", linewidth=1.0)]
    labels += [f"landmark {n_std:g}-sigma", f"pose {n_std:g}-sigma"]
    fig.tight_layout(rect=(0.0, 0.6 / fig.get_figheight(), 1.0, 1.0))  # room for the legend
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize="small")
    return fig


def plot_correlation_snapshots(
    covs,
    steps,
    dt: float,
    *,
    title: str = "Correlation coefficients of the EKF-SLAM state",
):
    """The correlation matrix of the whole state at chosen steps, as images (blank: not in map)."""
    sig = as_array("covs", covs, ndim=3)
    k = (sig.shape[1] - 3) // 2
    names = state_labels(k)
    fig, axes = plt.subplots(1, len(steps), figsize=(min(4.0 * len(steps) + 1.2, 13.0), 4.6),
                             squeeze=False, sharey=True, constrained_layout=True)
    axes = list(axes.flat)
    fig.suptitle(title)
    image = None
    for ax, t in zip(axes, steps, strict=True):
        rho = correlation_matrix(sig[t])
        image = ax.imshow(rho, cmap="RdBu_r", vmin=-1, vmax=1, interpolation="nearest")
        ax.set_xticks(range(len(names)))
        ax.set_yticks(range(len(names)))
        ax.set_xticklabels(names, rotation=90, fontsize=7)
        ax.tick_params(axis="y", labelsize=7)
        ax.set_title(f"after {t * dt:g} s", fontsize="medium")
        ax.set_xlabel("state entry")
    axes[0].set_yticklabels(names)
    axes[0].set_ylabel("state entry")
    fig.colorbar(image, ax=axes, shrink=0.8, label="correlation coefficient")
    return fig


def plot_pose_errors(
    t,
    path,
    true_poses,
    pose_covs,
    *,
    n_std: float = 2.0,
    title: str = "EKF-SLAM pose error and its 2-sigma bound",
    dead_reckoning=None,
):
    """Position and heading error against time, with the filter's own ``n_std``-sigma bound."""
    tt = as_array("t", t, ndim=1)
    est = as_array("path", path, ndim=2)
    tru = as_array("true_poses", true_poses, ndim=2)
    cov = as_array("pose_covs", pose_covs, ndim=3)
    fig, (ax_p, ax_h) = plt.subplots(2, 1, figsize=(8.0, 6.0), sharex=True)
    fig.suptitle(title)
    err = np.hypot(*(est[:, :2] - tru[:, :2]).T)
    bound = n_std * np.sqrt(np.clip(cov[:, 0, 0] + cov[:, 1, 1], 0.0, None))
    ax_p.plot(tt, err, color="tab:orange", label="EKF-SLAM position error")
    ax_p.plot(tt, bound, color="tab:blue", linestyle="--",
              label=f"{n_std:g} x sqrt(var x + var y)")
    if dead_reckoning is not None:
        dr = as_array("dead_reckoning", dead_reckoning, ndim=2)
        ax_p.plot(tt, np.hypot(*(dr[:, :2] - tru[:, :2]).T), color="tab:gray", linestyle=":",
                  label="dead reckoning")
        ax_p.set_yscale("log")
    ax_p.set_ylabel("position error [m]")
    legend_outside(ax_p)
    heading = (est[:, 2] - tru[:, 2] + np.pi) % (2 * np.pi) - np.pi
    sd = n_std * np.sqrt(np.clip(cov[:, 2, 2], 0.0, None))
    ax_h.plot(tt, heading, color="tab:orange", label="heading error")
    ax_h.fill_between(tt, -sd, sd, color="tab:blue", alpha=0.25, label=f"±{n_std:g} sigma")
    ax_h.set_ylabel("heading error [rad]")
    ax_h.set_xlabel("time [s]")
    legend_outside(ax_h)
    for ax in (ax_p, ax_h):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def plot_entries_changed(
    n_landmarks,
    changed: dict,
    ax: Axes | None = None,
    *,
    title: str = "Covariance entries one step changes",
) -> Axes:
    """Log-log curves of how many entries of Sigma each operation changes, against K."""
    k = as_array("n_landmarks", n_landmarks, ndim=1)
    ax = new_axes(title, xlabel="landmarks in the state K", ylabel="entries changed",
                  equal=False) if ax is None else ax
    for label, values in changed.items():
        ax.loglog(k, as_array(label, values, ndim=1), marker="o", markersize=4, label=label)
    ax.loglog(k, (3 + 2 * k) ** 2, color="gray", linestyle=":", label="(3 + 2K)^2, all of Sigma")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper left", fontsize="small")
    return ax
