"""Figures for lab 03, the landmark particle filter in :class:`robolab.world.cWorld`.

Every function draws into ``ax`` when given and otherwise makes a titled,
labelled figure; each returns the Axes it drew on (or an array of Axes).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from robolab.plotting.core import new_axes, plot_particles
from robolab.validation import as_array

__all__ = [
    "plot_world_and_robots",
    "plot_paths",
    "plot_filter_run",
    "plot_error_vs_particles",
    "plot_count_variance",
    "plot_deprivation",
]


def _xy(name, value):
    arr = as_array(name, value, ndim=2, finite=True)
    if arr.shape[1] < 2:
        raise ValueError(f"{name} must have shape (T, 2) or (T, 3), got {arr.shape}")
    return arr[:, :2]


def plot_world_and_robots(
    world, robots=(), ax=None, *, title="cWorld with three robots (section a)"
):
    """Draw the world's landmarks and each robot (circle and heading line).

    Parameters
    ----------
    world : robolab.world.cWorld
    robots : sequence of robolab.world.cRobot
    ax : Axes, optional
    title : str

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        ax = new_axes(title, figsize=(6.0, 6.0))
    else:
        ax.set_title(title)
    world.plot(ax)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, robot in enumerate(robots):
        robot.plot(
            ax,
            color=colors[i % len(colors)],
            label=f"robot {i + 1}: ({robot.x:g}, {robot.y:g}, {np.degrees(robot.theta):.0f} deg)",
        )
    ax.legend(loc="upper right", fontsize="small")
    return ax


def plot_paths(world, paths, ax=None, *, title="Paths in cWorld"):
    """Draw the world and several position paths.

    Parameters
    ----------
    world : robolab.world.cWorld
    paths : dict
        ``{label: (array (T, 2) or (T, 3), matplotlib format string)}``, drawn in order.
    ax : Axes, optional
    title : str

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        ax = new_axes(title, figsize=(6.0, 6.0))
    else:
        ax.set_title(title)
    world.plot(ax)
    for label, (path, fmt) in paths.items():
        xy = _xy(label, path)
        ax.plot(xy[:, 0], xy[:, 1], fmt, label=label, markersize=4)
    ax.legend(loc="upper right", fontsize="small")
    return ax


def plot_filter_run(
    world,
    history,
    command_path,
    true_path,
    ax=None,
    *,
    title="Particle filter (section g)",
    measurements=None,
):
    """The section-g figure: particles, command, true and estimated paths.

    Parameters
    ----------
    world : robolab.world.cWorld
    history : dict
        What ``particle_filter(..., return_history=True)`` returns: ``"path"``
        (T+1, 2), ``"predicted"`` (T, N, 3), ``"resampled"`` (T, N, 3).
    command_path, true_path : array_like, shape (T+1, 2)
    ax : Axes, optional
    title : str
    measurements : array_like, shape (T, K), optional
        When given, a circle of the measured range around each landmark is drawn
        for the last step (faint), to show where the measurement puts the robot.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        ax = new_axes(title, figsize=(9.5, 7.0))
    else:
        ax.set_title(title)
    world.plot(ax)
    predicted = as_array("history['predicted']", history["predicted"], ndim=3)
    resampled = as_array("history['resampled']", history["resampled"], ndim=3)
    for t in range(len(predicted)):
        plot_particles(
            predicted[t],
            ax=ax,
            color="k",
            size=4.0,
            alpha=0.5,
            label="projected particles" if t == 0 else None,
        )
        plot_particles(
            resampled[t],
            ax=ax,
            color="0.6",
            size=14.0,
            alpha=0.5,
            label="resampled particles" if t == 0 else None,
        )
    if measurements is not None:
        z = as_array("measurements", measurements, ndim=2)
        for k, ((lx, ly), r) in enumerate(zip(world.landmarks, z[-1], strict=True)):
            ax.add_patch(
                plt.Circle(
                    (lx, ly),
                    r,
                    fill=False,
                    color="tab:red",
                    alpha=0.25,
                    linestyle="--",
                    label="measured ranges, last step" if k == 0 else None,
                )
            )
    c, tr, est = (
        _xy("command_path", command_path),
        _xy("true_path", true_path),
        _xy("path", history["path"]),
    )
    ax.plot(c[:, 0], c[:, 1], "k:", label="command")
    ax.plot(tr[:, 0], tr[:, 1], "k-o", markersize=3, label="true position")
    ax.plot(est[:, 0], est[:, 1], "b-s", markersize=3, label="estimated position")
    ax.set_xlim(0, world.size)
    ax.set_ylim(0, world.size)
    ax.set_aspect("equal", adjustable="box")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize="small")
    ax.figure.tight_layout()
    return ax


def plot_error_vs_particles(
    n_particles, errors, ax=None, *, title="Final position error against the number of particles"
):
    """Each run's error (dots) and the mean per N (line), on a log N axis.

    Parameters
    ----------
    n_particles : array_like, shape (M,)
    errors : array_like, shape (M, S)
        Error of each of S seeded runs for each N [m].
    ax : Axes, optional
    title : str

    Returns
    -------
    matplotlib.axes.Axes
    """
    n = as_array("n_particles", n_particles, ndim=1)
    e = as_array("errors", errors, shape=(len(n), None))
    if ax is None:
        ax = new_axes(
            title, xlabel="number of particles N", ylabel="final position error [m]", equal=False
        )
    else:
        ax.set_title(title)
    jitter = np.exp(np.linspace(-0.08, 0.08, e.shape[1]))
    ax.scatter(
        (n[:, None] * jitter).ravel(),
        e.ravel(),
        s=10,
        color="0.5",
        alpha=0.7,
        label="one seeded run",
    )
    ax.plot(n, e.mean(axis=1), "b-o", label="mean over runs")
    ax.set_xscale("log")
    ax.set_ylim(bottom=0)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return ax


def plot_count_variance(
    expected_counts,
    var_low_variance,
    var_multinomial,
    ax=None,
    *,
    title="Variance of the number of copies of each particle",
):
    """Measured variance of each particle's copy count for two resamplers, with theory.

    Multinomial resampling gives ``Var = N w (1 - w)``; low-variance
    (systematic) resampling ``Var = p (1 - p)`` with ``p = frac(N w)``, at most 1/4.

    Parameters
    ----------
    expected_counts : array_like, shape (N,)
        ``N w_i`` for each particle.
    var_low_variance, var_multinomial : array_like, shape (N,)
        Measured variances of the counts over repeated resamplings.
    ax : Axes, optional
    title : str

    Returns
    -------
    matplotlib.axes.Axes
    """
    m = as_array("expected_counts", expected_counts, ndim=1)
    vl = as_array("var_low_variance", var_low_variance, shape=(len(m),))
    vm = as_array("var_multinomial", var_multinomial, shape=(len(m),))
    if ax is None:
        ax = new_axes(
            title, xlabel="expected copies N w_i", ylabel="variance of the copy count", equal=False
        )
    else:
        ax.set_title(title)
    n = len(m)
    grid = np.linspace(0, m.max(), 400)
    ax.plot(grid, grid * (1 - grid / n), "r-", lw=1, label="theory, multinomial: N w (1 - w)")
    frac = grid - np.floor(grid)
    ax.plot(
        grid, frac * (1 - frac), "b-", lw=1, label="theory, low-variance: p (1 - p), p = frac(N w)"
    )
    ax.scatter(m, vm, s=12, color="tab:red", alpha=0.7, label="multinomial (measured)")
    ax.scatter(m, vl, s=12, color="tab:blue", alpha=0.7, label="low-variance (measured)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_deprivation(
    errors,
    distinct,
    labels,
    axes=None,
    *,
    title="Particle deprivation: sensor noise assumed by the filter",
):
    """Two panels: position error per model setting (box plot) and distinct particles per step.

    Parameters
    ----------
    errors : sequence of array_like, shape (R,)
        For each setting, the mean position error of R runs [m].
    distinct : sequence of array_like, shape (T,)
        For each setting, the mean number of distinct particles after each resampling.
    labels : sequence of str
        One label per setting.
    axes : sequence of two Axes, optional
    title : str

    Returns
    -------
    numpy.ndarray of two Axes
    """
    if not len(errors) == len(distinct) == len(labels):
        raise ValueError("errors, distinct and labels must have one entry per setting")
    if axes is None:
        fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.2))
    axes = np.asarray(axes)
    fig = axes[0].figure
    fig.suptitle(title)
    axes[0].boxplot([np.asarray(e, dtype=float) for e in errors], tick_labels=list(labels))
    axes[0].set_title("mean position error over the path")
    axes[0].set_xlabel("filter's model")
    axes[0].set_ylabel("error [m]")
    for d, label in zip(distinct, labels, strict=True):
        d = np.asarray(d, dtype=float)
        axes[1].plot(np.arange(1, len(d) + 1), d, "-o", label=label)
    axes[1].set_yscale("log")
    axes[1].set_title("distinct particles after resampling")
    axes[1].set_xlabel("time step t")
    axes[1].set_ylabel("number of distinct particles (of N)")
    axes[1].legend()
    axes[1].grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return axes
