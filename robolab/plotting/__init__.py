"""Figures for the labs.

``robolab.plotting.core`` holds the figures every lab uses (maps, poses,
particles, landmarks, covariance ellipses, scans, discrete beliefs), re-exported
here; lab-specific figures live in ``robolab.plotting.<topic>`` modules.
Every function returns the Axes (or artist) it drew, so figures compose; none
calls ``plt.show()``.
"""

from robolab.plotting.core import (
    UNKNOWN_COLOR,
    covariance_ellipse_params,
    new_axes,
    plot_belief,
    plot_covariance_ellipse,
    plot_landmarks,
    plot_map,
    plot_particles,
    plot_poses,
    plot_scan,
)

__all__ = [
    "UNKNOWN_COLOR",
    "covariance_ellipse_params",
    "new_axes",
    "plot_belief",
    "plot_covariance_ellipse",
    "plot_landmarks",
    "plot_map",
    "plot_particles",
    "plot_poses",
    "plot_scan",
]
