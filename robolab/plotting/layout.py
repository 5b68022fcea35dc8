"""Figure layout shared by every figure: titled axes, panel grids, legends outside the data.

The conventions (docs/figures.md): every figure has a title and axes labelled with
units, panels fit a notebook's width, legends never cover the data, and scatter
markers in a legend stay readable however fine the cloud they stand for.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.collections import PathCollection
from matplotlib.legend import Legend
from matplotlib.legend_handler import HandlerPathCollection

__all__ = ["new_axes", "panel_grid", "legend_outside", "LEGEND_MARKER_AREA", "NOTEBOOK_WIDTH"]


def new_axes(
    title: str,
    xlabel: str = "x [m]",
    ylabel: str = "y [m]",
    equal: bool = True,
    *,
    figsize: tuple[float, float] = (6.0, 5.0),
) -> Axes:
    """Create a figure with one titled, labelled Axes and return the Axes.

    Parameters
    ----------
    title : str
        Figure title (required: every figure in the workbook has one).
    xlabel, ylabel : str
        Axis labels, with units in brackets.
    equal : bool
        Use an equal aspect ratio (right for maps and trajectories, wrong for
        plots of a probability over a position).
    figsize : (float, float)
        Figure size in inches.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if not isinstance(title, str) or not title.strip():
        raise ValueError(f"title must be a non-empty string, got {title!r}")
    _, ax = plt.subplots(figsize=figsize)
    ax.set_title(title)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if equal:
        ax.set_aspect("equal", adjustable="datalim")
    return ax


#: Smallest area (points^2) of a scatter marker in a legend: a fine particle cloud keeps
#: its small markers on the plot, but its legend entry stays readable (docs/figures.md).
LEGEND_MARKER_AREA = 30.0


class _ReadableMarkers(HandlerPathCollection):
    """Legend handler that draws scatter markers at least :data:`LEGEND_MARKER_AREA` big."""

    def get_sizes(self, legend, orig_handle, xdescent, ydescent, width, height, fontsize):
        sizes = super().get_sizes(legend, orig_handle, xdescent, ydescent, width, height, fontsize)
        return [max(float(size), LEGEND_MARKER_AREA) for size in sizes]

    def update_prop(self, legend_handle, orig_handle, legend):
        super().update_prop(legend_handle, orig_handle, legend)
        alpha = orig_handle.get_alpha()
        if alpha is not None and alpha < 0.6:
            legend_handle.set_alpha(0.6)  # a faint cloud still gets a legible swatch


Legend.update_default_handler_map({PathCollection: _ReadableMarkers()})


#: Widest figure that fits a notebook at 100 % zoom without scrolling, inches.
NOTEBOOK_WIDTH = 13.0


def panel_grid(
    n: int,
    *,
    panel: tuple[float, float] = (4.2, 3.6),
    max_cols: int = 3,
    title: str | None = None,
    **subplots_kw,
) -> tuple[plt.Figure, list[Axes]]:
    """A figure of ``n`` panels, at most ``max_cols`` per row, that fits the notebook width.

    Panels keep the size ``panel`` (inches) unless a row would be wider than
    :data:`NOTEBOOK_WIDTH`, in which case they shrink to fit; unused cells of the last
    row are switched off. See docs/figures.md.

    Returns
    -------
    (Figure, list of Axes)
        The figure and its ``n`` panels in reading order.
    """
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    rows = -(-n // max_cols)
    cols = -(-n // rows)  # balanced rows: 4 panels are 2 x 2, not 3 + 1
    scale = min(1.0, NOTEBOOK_WIDTH / (panel[0] * cols))
    size = (max(panel[0] * cols * scale, 5.0), panel[1] * rows * scale + (0.4 if title else 0.0))
    fig, axes = plt.subplots(rows, cols, figsize=size, squeeze=False, **subplots_kw)
    flat = list(axes.flat)
    for ax in flat[n:]:
        ax.axis("off")
    if title:
        fig.suptitle(title)
    return fig, flat[:n]


def legend_outside(ax: Axes, **kw):
    """Put the legend to the right of the panel, where it cannot cover the data."""
    kw.setdefault("loc", "upper left")
    kw.setdefault("bbox_to_anchor", (1.02, 1.0))
    kw.setdefault("borderaxespad", 0.0)
    kw.setdefault("fontsize", "small")
    return ax.legend(**kw)


def _axes(ax: Axes | None, default_title: str, title: str | None, **kw) -> Axes:
    """``ax`` (retitled when ``title`` is given) or a new Axes titled ``title or default_title``."""
    if ax is None:
        return new_axes(title or default_title, **kw)
    if not isinstance(ax, Axes):
        raise TypeError(f"ax must be a matplotlib Axes or None, got {type(ax).__name__}")
    if title is not None:
        ax.set_title(title)
    return ax
