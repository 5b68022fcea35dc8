"""Check figures against the style guide (docs/figures.md): titles, labels, legends, size.

:func:`audit_figure` returns the problems of one figure as sentences. As an IPython
extension (``%load_ext robolab.plotting.audit``) it audits every figure a cell leaves
open and every value a cell displays, so that a notebook run (``make test`` runs the
solved notebooks this way) fails on an untitled figure, an axis without a label, a
legend entry whose artist cannot be seen or that covers the data, or a stray repr
such as ``<matplotlib.legend.Legend at 0x...>`` or ``np.float64(0.5)``;
:func:`report` raises with everything found. With ``ROBOLAB_AUDIT_SAVE=folder`` in the
kernel's environment every audited figure is also saved there as a PNG, to look at.

What counts as a problem (each rule is in docs/figures.md):

- a figure without a title (its suptitle, or a title on its first panel);
- a panel with data whose x or y axis is shown but has no label (colour bars,
  panels with their axes switched off, and panels sharing the axis with a labelled
  panel of the same figure are exempt);
- a legend entry whose artist is invisible (alpha < 0.25, a marker smaller than
  2 points with no line, a line thinner than 0.5 points with no marker, an empty
  collection), is drawn in the legend smaller than 3 points, or has nothing
  inside the panel's view;
- a legend that covers more than 5 % of the data points of the panel it labels;
- a figure narrower than 5 inches or wider than 14 (notebook width), or a panel
  smaller than 2.0 x 0.9 inches.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["audit_figure", "audit_value", "load_ipython_extension", "report"]

#: Smallest marker (points) that a reader can see in a legend.
MIN_MARKER = 3.0
#: Smallest marker (points) of a plotted artist (a dense particle cloud may be this fine).
MIN_DATA_MARKER = 2.0
#: Thinnest line (points) that counts as drawn.
MIN_LINE = 0.5
#: Lowest alpha that counts as visible for lines and markers.
MIN_ALPHA = 0.25
#: Lowest alpha that counts as visible for filled areas (bands, patches).
MIN_AREA_ALPHA = 0.12
#: Largest share of a panel's data points that a legend may hide.
MAX_COVERED = 0.05
#: Notebook width in inches (JupyterLab at 100 % zoom shows about 9.5 in at dpi 100).
FIG_WIDTH = (5.0, 14.0)
#: Smallest readable panel, inches.
MIN_PANEL = (2.0, 0.9)

_REPR = re.compile(
    r"^(<matplotlib\.[\w.]+ (object )?at 0x[0-9a-f]+>|np\.(float|int|bool)\w*\(.*\))$"
)


def _alpha(artist: Any) -> float:
    alpha = artist.get_alpha()
    return 1.0 if alpha is None else float(alpha)


def _points_in_view(ax: Any, xy: np.ndarray) -> np.ndarray:
    """Boolean mask of the data points ``xy`` (N, 2) inside the panel's view limits."""
    if xy.size == 0:
        return np.zeros(0, bool)
    x0, x1 = sorted(ax.get_xlim())
    y0, y1 = sorted(ax.get_ylim())
    finite = np.isfinite(xy).all(axis=1)
    return finite & (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)


def _data_points(artist: Any) -> np.ndarray | None:
    """The data coordinates an artist draws, (N, 2), or None when it has no point data."""
    from matplotlib.collections import Collection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    if getattr(artist, "axes", None) is None:
        return None  # a proxy artist made only for the legend
    if isinstance(artist, Line2D):
        return np.column_stack([np.asarray(artist.get_xdata(), float).ravel(),
                                np.asarray(artist.get_ydata(), float).ravel()])
    if isinstance(artist, Collection):
        offsets = np.asarray(artist.get_offsets(), float).reshape(-1, 2)
        if len(offsets) and artist.get_offset_transform() is artist.axes.transData:
            return offsets
        paths = artist.get_paths()
        if paths:
            verts = [p.vertices for p in paths if len(p.vertices)]
            if verts and artist.get_transform() is artist.axes.transData:
                return np.concatenate(verts)
        return offsets if len(offsets) else None
    if isinstance(artist, Patch):
        try:
            box = artist.get_window_extent()
        except (RuntimeError, ValueError):
            return None
        inv = artist.axes.transData.inverted()
        return inv.transform(np.array([[box.x0, box.y0], [box.x1, box.y1],
                                       [(box.x0 + box.x1) / 2, (box.y0 + box.y1) / 2]]))
    return None


def _invisible(handle: Any, min_marker: float) -> str | None:
    """Why an artist (or a legend's drawn handle) cannot be seen, or None."""
    from matplotlib.collections import Collection, PathCollection
    from matplotlib.lines import Line2D

    if not handle.get_visible():
        return "is hidden"
    floor = MIN_ALPHA if not isinstance(handle, Collection) or isinstance(
        handle, PathCollection) else MIN_AREA_ALPHA
    if _alpha(handle) < floor:
        return f"has alpha {_alpha(handle):.2f}"
    if isinstance(handle, Line2D):
        marker = handle.get_marker() not in (None, "None", "none", "", " ")
        line = (handle.get_linestyle() not in ("None", "none", "", " ")
                and handle.get_linewidth() >= MIN_LINE)
        if not line and (not marker or handle.get_markersize() < min_marker):
            return f"is a marker of {handle.get_markersize():g} pt with no line"
    if isinstance(handle, Collection):
        if len(handle.get_paths()) == 0:
            return "is empty"
        widths = np.asarray(handle.get_linewidths(), float)
        face = np.asarray(handle.get_facecolors(), float).reshape(-1, 4)
        edge = np.asarray(handle.get_edgecolors(), float).reshape(-1, 4)
        # Face and edge colours already carry the artist's alpha.
        # A filled area (a band, a patch) reads at a lower alpha than a marker does.
        floor = MIN_ALPHA if isinstance(handle, PathCollection) else MIN_AREA_ALPHA
        seen_face = face.size and face[:, 3].max() >= floor
        seen_edge = (edge.size and edge[:, 3].max() >= MIN_ALPHA
                     and widths.size and widths.max() >= MIN_LINE)
        if not (seen_face or seen_edge):
            return "has no visible face or edge"
        if isinstance(handle, PathCollection):  # scatter markers: sizes are areas in pt^2
            sizes = np.asarray(handle.get_sizes(), float)
            if sizes.size and np.sqrt(sizes.max()) < min_marker:
                return f"has markers of {np.sqrt(sizes.max()):.1f} pt (at least {min_marker:g})"
    return None


def _legend_problems(ax: Any, where: str) -> list[str]:
    legend = ax.get_legend()
    if legend is None or not legend.get_visible():
        return []
    problems = []
    handles, labels = ax.get_legend_handles_labels()
    drawn = getattr(legend, "legend_handles", None) or getattr(legend, "legendHandles", [])
    drawn = [*drawn, *[None] * (len(handles) - len(drawn))][: len(handles)]
    for handle, label, shown in zip(handles, labels, drawn, strict=True):
        why = _invisible(handle, MIN_DATA_MARKER)
        if why is None and shown is not None:
            why = _invisible(shown, MIN_MARKER)
            why = why and f"is drawn in the legend so that it {why.replace('is ', 'is ', 1)}"
        if why:
            problems.append(f"{where}: legend entry {label!r} {why}")
            continue
        points = _data_points(handle)
        if points is not None and len(points) and not _points_in_view(ax, points).any():
            problems.append(f"{where}: legend entry {label!r} has nothing inside the panel")
    # A legend placed outside the panel (bbox_to_anchor beyond [0, 1]) covers nothing.
    box = legend.get_window_extent()
    panel = ax.get_window_extent()
    outside = (box.x0 >= panel.x1 - 1 or box.x1 <= panel.x0 + 1
               or box.y0 >= panel.y1 - 1 or box.y1 <= panel.y0 + 1)
    if outside:
        return problems
    total = covered = 0
    for artist in [*ax.lines, *ax.collections]:
        if not artist.get_visible():
            continue
        points = _data_points(artist)
        if points is None or not len(points):
            continue
        points = points[_points_in_view(ax, points)]
        if not len(points):
            continue
        display = ax.transData.transform(points)
        inside = ((display[:, 0] >= box.x0) & (display[:, 0] <= box.x1)
                  & (display[:, 1] >= box.y0) & (display[:, 1] <= box.y1))
        total += len(points)
        covered += int(inside.sum())
    if total >= 20 and covered > MAX_COVERED * total:
        problems.append(
            f"{where}: the legend covers {100 * covered / total:.0f} % of the data points; "
            "move it outside the panel or to an empty corner"
        )
    return problems


def _is_colorbar(ax: Any) -> bool:
    return ax.get_label() == "<colorbar>" or hasattr(ax, "_colorbar")


def _has_data(ax: Any) -> bool:
    return bool(ax.lines or ax.collections or ax.images or ax.patches or ax.containers)


def _labelled(ax: Any, panels: list, axis: str) -> bool:
    """The axis has a label, no ticks, or shares its scale with a labelled panel."""
    if getattr(ax, f"get_{axis}label")() or not getattr(ax, f"get_{axis}ticks")().size:
        return True
    shared = getattr(ax, f"get_shared_{axis}_axes")()
    return any(
        other is not ax and shared.joined(ax, other) and getattr(other, f"get_{axis}label")()
        for other in panels
    )


def audit_figure(fig: Any, name: str = "figure") -> list[str]:
    """Return the style-guide problems of one matplotlib figure (empty when it is fine).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    name : str
        How to name the figure in the sentences (e.g. ``"cell 12, figure 2"``).

    Returns
    -------
    list of str
        One sentence per problem, naming the panel by its title when it has one.
    """
    problems: list[str] = []
    fig.canvas.draw()  # legends and tight layouts are placed only when drawn
    width, height = fig.get_size_inches()
    if not FIG_WIDTH[0] <= width <= FIG_WIDTH[1]:
        problems.append(f"{name}: {width:.1f} in wide; notebook figures are "
                        f"{FIG_WIDTH[0]:g}-{FIG_WIDTH[1]:g} in wide")
    suptitle = fig._suptitle.get_text() if getattr(fig, "_suptitle", None) else ""
    panels = [ax for ax in fig.axes if ax.get_visible() and not _is_colorbar(ax) and _has_data(ax)]
    if not panels:
        return problems
    if not suptitle and not (panels[0].get_title() or panels[0].get_title("left")):
        problems.append(f"{name}: no title (set a suptitle or a title on the first panel)")
    dpi = fig.dpi
    for index, ax in enumerate(panels):
        where = f"{name}, panel {ax.get_title() or suptitle or index + 1!r}"
        box = ax.get_window_extent()
        if box.width / dpi < MIN_PANEL[0] or box.height / dpi < MIN_PANEL[1]:
            problems.append(
                f"{where}: {box.width / dpi:.1f} x {box.height / dpi:.1f} in, too small "
                f"to read (at least {MIN_PANEL[0]:g} x {MIN_PANEL[1]:g} in)"
            )
        if ax.axison:
            if ax.xaxis.get_visible() and not _labelled(ax, panels, "x"):
                problems.append(f"{where}: the x axis has no label")
            if ax.yaxis.get_visible() and not _labelled(ax, panels, "y"):
                problems.append(f"{where}: the y axis has no label")
        problems += _legend_problems(ax, where)
    return problems


def audit_value(value: Any) -> str | None:
    """A sentence when a cell's displayed value is a stray repr (end the line with ``;``)."""
    if value is None:
        return None
    module = type(value).__module__ or ""
    if module.startswith("matplotlib") or isinstance(value, (list, tuple)) and value and all(
        (type(v).__module__ or "").startswith("matplotlib") for v in value
    ):
        return f"displays {type(value).__name__} (end the line with `;` or assign it)"
    if isinstance(value, np.generic) and _REPR.match(repr(value)):
        return f"displays {value!r}: print it with a sentence, or convert it (float(...))"
    return None


def _quiet(cell: str) -> bool:
    """True when Jupyter shows no value for the cell: its last code token is ``;``.

    (Newer IPython versions keep the last expression's value in ``result.result`` even
    when the semicolon suppresses its display, so the value alone does not tell.)
    """
    import io
    import tokenize

    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(cell).readline))
    except (tokenize.TokenError, SyntaxError, IndentationError):
        return cell.rstrip().endswith(";")
    skip = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.ENDMARKER,
            tokenize.INDENT, tokenize.DEDENT}
    code = [t for t in tokens if t.type not in skip]
    return bool(code) and code[-1].string == ";"


class _Auditor:
    def __init__(self, shell: Any) -> None:
        self.shell = shell
        self.seen: set[int] = set()
        self.problems: list[str] = []
        self.printed: list[str] = []  # numpy reprs in printed text (_PrintedReprs)
        self.cell = 0
        self.raw_cell = ""
        folder = os.environ.get("ROBOLAB_AUDIT_SAVE")
        self.save_to = Path(folder) if folder else None

    def pre_run_cell(self, info: Any) -> None:
        self.raw_cell = info.raw_cell or ""

    def where(self, number: int) -> str:
        first = self.raw_cell.strip().splitlines()[:1]
        return f"cell {number} ({first[0][:50]!r})" if first else f"cell {number}"

    def post_execute(self) -> None:
        """Audit the cell's figures before the inline backend shows and closes them."""
        self.audit_figures(self.where(self.cell + 1))

    def post_run_cell(self, result: Any) -> None:
        self.cell += 1
        where = self.where(self.cell)
        if not _quiet(result.info.raw_cell or "") and (why := audit_value(result.result)):
            self.problems.append(f"{where}: {why}")
        self.audit_figures(where)  # figures left open (a non-inline backend)

    def audit_figures(self, where: str) -> None:
        import matplotlib.pyplot as plt

        for number in plt.get_fignums():
            fig = plt.figure(number)
            if id(fig) in self.seen:
                continue
            self.seen.add(id(fig))
            self.problems += audit_figure(fig, f"{where}, figure {number}")
            if self.save_to is not None:  # to look at every figure of a run as PNG files
                self.save_to.mkdir(parents=True, exist_ok=True)
                # as Jupyter shows it: the inline backend crops to the drawn extent
                fig.savefig(self.save_to / f"cell{self.cell:03d}_fig{number}.png", dpi=72,
                            bbox_inches="tight")
            plt.close(fig)


class _PrintedReprs:
    """A stream wrapper that notes numpy scalar reprs (``np.float64(0.5)``) in printed text.

    ``print(f"{x}")`` of a numpy scalar is fine; a tuple or list of them, or ``{x!r}``,
    prints ``np.float64(...)`` since numpy 2: noise a student should not have to read.
    """

    PATTERN = re.compile(r"\bnp\.(?:float|int|uint|bool|complex|str_|bytes_)\w*\(")

    def __init__(self, stream: Any, auditor: _Auditor) -> None:
        self._stream, self._auditor = stream, auditor

    def write(self, text: str) -> int:
        if isinstance(text, str) and (match := self.PATTERN.search(text)):
            shown = text[max(0, match.start() - 20) : match.end() + 20].strip()
            self._auditor.printed.append(
                f"cell {self._auditor.cell + 1}: prints a numpy repr ({shown!r}): "
                "convert to float/int or format it"
            )
        return self._stream.write(text)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


_AUDITOR: _Auditor | None = None


def load_ipython_extension(shell: Any) -> None:
    """``%load_ext robolab.plotting.audit``: audit every later cell's figures and values."""
    global _AUDITOR
    _AUDITOR = _Auditor(shell)
    shell.events.register("pre_run_cell", _AUDITOR.pre_run_cell)
    # before the inline backend's own post_execute hook, which shows and closes figures
    shell.events.callbacks["post_execute"].insert(0, _AUDITOR.post_execute)
    shell.events.register("post_run_cell", _AUDITOR.post_run_cell)
    if not isinstance(sys.stdout, _PrintedReprs):
        sys.stdout = _PrintedReprs(sys.stdout, _AUDITOR)


def report() -> None:
    """Raise AssertionError listing every problem the extension found (call in the last cell)."""
    if _AUDITOR is None:
        raise RuntimeError("load the extension first: %load_ext robolab.plotting.audit")
    problems = _AUDITOR.problems + _AUDITOR.printed
    if problems:
        raise AssertionError(
            f"{len(problems)} figure or output problem(s) (see docs/figures.md):\n  "
            + "\n  ".join(problems)
        )
    import resource

    usage = resource.getrusage(resource.RUSAGE_SELF)
    print(f"figure audit: {len(_AUDITOR.seen)} figure(s), no problem; "
          f"kernel CPU {usage.ru_utime + usage.ru_stime:.1f} s")
