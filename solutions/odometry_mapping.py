r"""Lab 04 reference solution: occupancy grid mapping with raw odometry.

Seed 004, part 2 ("Mapping with Raw Odometry"): the simple counting
algorithm, clipped at 0.5, built from the bundled ``data/mapping.bag``; then,
beyond the seed, the log-odds occupancy grid of Probabilistic Robotics
(Table 9.1) with the inverse range sensor model (Table 9.2).

Conventions used by every function here
---------------------------------------
* A **scan** is a dict of plain data: ``ranges`` (B,) metres, ``angles`` (B,)
  radians in the laser frame, ``range_min`` and ``range_max`` (floats, metres).
* Beams are sorted into three kinds, as sensor_msgs/LaserScan and REP-117 say:

  - **hit**: finite, ``> 0`` and ``range_min <= r < range_max``: the beam ended
    on an obstacle at range ``r``;
  - **no return**: ``+inf`` or ``r >= range_max`` (a max-range reading): nothing
    was detected within ``range_max``, so the beam is evidence of free space up
    to ``range_max`` and of no obstacle anywhere (Table 9.2 treats ``z = z_max``
    the same way: free cells, never an occupied one);
  - **invalid**: NaN, ``-inf``, ``r <= 0`` or ``r < range_min``: no information;
    the beam is ignored (clearing cells along it would erase real obstacles).

* Map cells follow :class:`robolab.maps.OccupancyGrid`: ``data[row, col]``,
  row = y. *Continuous cell coordinates* ``(row, col)`` are
  ``grid.world_to_map(xy)[..., ::-1]``: cell ``(i, j)`` is the half-open square
  ``[i, i + 1) x [j, j + 1)``, so ``floor`` of a point's coordinates is the cell
  :meth:`~robolab.maps.OccupancyGrid.world_to_cell` gives.
* ``pose`` in the map-update functions is the **laser's** pose in the map frame,
  ``compose(robot_pose, laser_offset)``: the beams start there.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.special import expit

from robolab.geometry import compose, transform_points, wrap_angle
from robolab.maps import UNKNOWN, OccupancyGrid
from robolab.validation import as_array, check_positive

__all__ = [
    "scan_endpoints",
    "beam_cells",
    "counting_map_update",
    "occupancy_from_counts",
    "clip_map",
    "logodds_update",
    "logodds_to_probability",
    "INVERSE_SENSOR_MODEL",
]

#: Default parameters of the inverse range sensor model (Table 9.2): log-odds of
#: an occupied (p = 0.7) and a free (p = 0.35) cell, the prior l_0 (p = 0.5),
#: the obstacle thickness in cells (``alpha_cells``: two cells, whatever the map's
#: resolution; ``alpha`` in metres may be given instead) and the beam width
#: beta (radians, two degrees: twice the bundled laser's angular increment).
INVERSE_SENSOR_MODEL = {
    "l_occ": float(np.log(0.7 / 0.3)),
    "l_free": float(np.log(0.35 / 0.65)),
    "l_0": 0.0,
    "alpha_cells": 2.0,
    "beta": float(np.deg2rad(2.0)),
}

_SCAN_KEYS = ("ranges", "angles", "range_min", "range_max")
#: Most cells :func:`beam_cells` returns in one call (two int64 each: 256 MiB).
MAX_BEAM_CELLS = 2**24


def _scan_arrays(scan):
    """Validate a scan dict; return ``ranges (B,), angles (B,), range_min, range_max``."""
    if not isinstance(scan, Mapping):
        raise TypeError(
            f"scan must be a dict with keys {', '.join(_SCAN_KEYS)}, got {type(scan).__name__}"
        )
    missing = [k for k in _SCAN_KEYS if k not in scan]
    if missing:
        raise ValueError(
            f"scan lacks key(s) {', '.join(missing)}; expected {', '.join(_SCAN_KEYS)}"
        )
    ranges = as_array("scan['ranges']", scan["ranges"], ndim=1)
    angles = as_array("scan['angles']", scan["angles"], shape=(ranges.size,), finite=True)
    rmin = check_positive("scan['range_min']", scan["range_min"], allow_zero=True)
    rmax = check_positive("scan['range_max']", scan["range_max"])
    if rmin >= rmax:
        raise ValueError(f"scan['range_min'] ({rmin}) must be < scan['range_max'] ({rmax})")
    return ranges, angles, rmin, rmax


def _beam_kinds(ranges, range_min, range_max):
    """Boolean masks ``(hit, no_return)`` of the beams (see the module docstring)."""
    with np.errstate(invalid="ignore"):
        hit = np.isfinite(ranges) & (ranges > 0) & (ranges >= range_min) & (ranges < range_max)
        no_return = (ranges >= range_max) & (ranges > 0)  # +inf, range_max and beyond; NaN is False
    return hit, no_return


def _pose(name, value):
    return as_array(name, value, shape=(3,), finite=True)


def _check_grid(grid):
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be a robolab.maps.OccupancyGrid, got {type(grid).__name__}")
    return grid


def _layer(name, value, grid, counts=False):
    """A float copy of a per-cell array of the grid's shape, checked finite (and >= 0 for counts).

    Besides the copy (the updates return new arrays), the check is two reductions
    -- min and max propagate NaN and are infinite exactly when an entry is -- and
    no per-cell temporaries, so an update's other work scales with the beams.
    """
    out = np.array(as_array(name, value, shape=grid.shape), dtype=float, order="C", copy=True)
    if out.size:
        lo, hi = out.min(), out.max()
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ValueError(f"{name} must be finite (no NaN or inf)")
        if counts and lo < 0:
            raise ValueError("hits and visits must be non-negative counts")
    return out


def scan_endpoints(scan, pose, laser_offset):
    r"""World coordinates of the endpoints of a scan's hit beams.

    The laser sits at ``x_s = pose (+) laser_offset`` (pose composition); beam
    ``k`` with range :math:`z_k` at angle :math:`\theta_k` (laser frame) ends at

    .. math::

        \begin{pmatrix} x_k \\ y_k \end{pmatrix} =
        \begin{pmatrix} x_s \\ y_s \end{pmatrix} + z_k
        \begin{pmatrix} \cos(\theta_s + \theta_k) \\ \sin(\theta_s + \theta_k) \end{pmatrix}

    (the endpoint equation of the likelihood field model, Probabilistic
    Robotics Table 6.3, line 4, with the sensor's mounting pose folded into
    :math:`x_s`).

    Only **hit** beams give endpoints: finite ranges with ``r > 0`` and
    ``range_min <= r < range_max``. NaN, 0, inf, ranges below ``range_min`` and
    max-range readings (``r >= range_max``: nothing detected) are left out; they
    are never turned into obstacles.

    Parameters
    ----------
    scan : dict
        ``ranges`` (B,) metres, ``angles`` (B,) radians in the laser frame,
        ``range_min``, ``range_max`` metres.
    pose : array_like, shape (3,)
        Robot (``base_link``) pose ``(x, y, theta)`` in the world.
    laser_offset : array_like, shape (3,)
        Laser pose in ``base_link`` (the ``base_link -> laser`` transform).

    Returns
    -------
    numpy.ndarray, shape (P, 2)
        ``(x, y)`` of each hit beam's endpoint, in the scan's beam order
        (``P`` = number of hit beams, possibly 0).

    Raises
    ------
    ValueError
        ``pose`` or ``laser_offset`` not three numbers, or a scan whose ranges and
        angles differ in length.
    """
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser_pose = compose(_pose("pose", pose), _pose("laser_offset", laser_offset))
    hit, _ = _beam_kinds(ranges, rmin, rmax)
    r, a = ranges[hit], angles[hit]
    return transform_points(np.stack([r * np.cos(a), r * np.sin(a)], -1), laser_pose)


def beam_cells(start_cell, end_cell):
    r"""Every grid cell a straight beam touches (exact supercover), for many beams at once.

    A beam is the closed segment :math:`p(t) = s + t\,(e - s)`, :math:`t \in [0, 1]`,
    in continuous cell coordinates ``(row, col)`` (``grid.world_to_map(xy)[..., ::-1]``).
    Cell ``(i, j)`` is the half-open square ``[i, i+1) x [j, j+1)``, the
    convention of :meth:`~robolab.maps.OccupancyGrid.world_to_cell`; the beam's
    cells are exactly

    .. math:: C(s, e) = \{ (\lfloor p_r(t) \rfloor, \lfloor p_c(t) \rfloor) : t \in [0, 1] \},

    every cell that contains a point of the segment and no other. The first cell
    is ``floor(s)`` and the last ``floor(e)``: the **end cell is included** (the
    counting algorithm counts it as visited and hit). A beam through a grid
    corner gets only the cells that own a point of it under the half-open
    convention (no extra corner neighbours); a beam along a grid line lies in
    the cells above / right of the line.

    The traversal is exact (not sampled): for each column ``j`` the beam
    crosses, the parameter interval on which ``j <= p_c(t) < j + 1`` gives the
    beam's row span in that column, and the cells are those rows (the column
    sweep form of Amanatides & Woo's grid traversal, 1987). Vectorized over
    beams and cells with no Python loop. Cells outside a map are returned too;
    the caller keeps those inside.

    Parameters
    ----------
    start_cell : array_like, shape (2,) or (B, 2)
        Beam start(s) ``(row, col)`` in continuous cell coordinates; one start
        is shared by all beams (the laser).
    end_cell : array_like, shape (2,) or (B, 2)
        Beam end(s) ``(row, col)``.

    Returns
    -------
    cells : numpy.ndarray of int64, shape (N, 2)
        ``(row, col)`` of the touched cells, beam after beam, each beam's cells
        ordered from its start cell to its end cell, no cell twice within a beam.
    beam : numpy.ndarray of int64, shape (N,)
        Index of the beam each cell belongs to (non-decreasing).

    Raises
    ------
    ValueError
        Shapes other than (2,) / (B, 2), mismatched B, non-finite coordinates,
        or beams that would cross more than :data:`MAX_BEAM_CELLS` cells in all.
    """
    s = as_array("start_cell", start_cell, ndim=(1, 2), finite=True)
    e = as_array("end_cell", end_cell, ndim=(1, 2), finite=True)
    if s.shape[-1] != 2:
        raise ValueError(f"start_cell must have shape (2,) or (B, 2), got {s.shape}")
    if e.shape[-1] != 2:
        raise ValueError(f"end_cell must have shape (2,) or (B, 2), got {e.shape}")
    s, e = np.atleast_2d(s), np.atleast_2d(e)
    if s.shape[0] != e.shape[0] and 1 not in (s.shape[0], e.shape[0]):
        raise ValueError(f"start_cell has {s.shape[0]} beams but end_cell has {e.shape[0]}")
    s, e = np.broadcast_arrays(s, e)
    # The beams touch at most |d row| + |d col| + 1 cells each: refuse before allocating.
    n_cells = float(np.sum(np.abs(np.floor(e) - np.floor(s)).sum(axis=1) + 1.0))
    if n_cells > MAX_BEAM_CELLS:
        raise ValueError(
            f"start_cell and end_cell: these beams cross up to {n_cells:.3g} cells, more than "
            f"MAX_BEAM_CELLS = {MAX_BEAM_CELLS}; clip the beams to the map first"
        )
    sr, sc, er, ec = s[:, 0], s[:, 1], e[:, 0], e[:, 1]
    dr, dc = er - sr, ec - sc
    n_beams = s.shape[0]

    # 1. the columns each beam crosses, in travel order
    c0 = np.floor(sc).astype(np.int64)
    c1 = np.floor(ec).astype(np.int64)
    ncol = np.abs(c1 - c0) + 1
    beam_c = np.repeat(np.arange(n_beams), ncol)
    k = np.arange(beam_c.size) - np.repeat(np.cumsum(ncol) - ncol, ncol)
    col = c0[beam_c] + k * np.where(c1 >= c0, 1, -1)[beam_c]
    first, last = k == 0, k == ncol[beam_c] - 1

    # 2. the parameter interval [t_lo, t_hi] on which the beam is in column `col`
    dcb, scb, srb, drb = dc[beam_c], sc[beam_c], sr[beam_c], dr[beam_c]
    with np.errstate(divide="ignore", invalid="ignore"):  # dc = 0 -> one column, overridden below
        t_left = (col - scb) / dcb  # where p_c = col
        t_right = (col + 1 - scb) / dcb  # where p_c = col + 1 (excluded from the column)
    pos = dcb > 0
    t_lo = np.where(first, 0.0, np.where(pos, t_left, t_right))
    t_hi = np.where(last, 1.0, np.where(pos, t_right, t_left))
    # The column's far edge x = col + 1 is not in it: moving right the interval is
    # open at t_hi, moving left open at t_lo (except at the segment's own ends).
    open_hi = pos & ~last
    open_lo = (dcb < 0) & ~first
    y_lo = np.where(first, srb, srb + t_lo * drb)  # exact ends: floor(e) is always the last cell
    y_hi = np.where(last, er[beam_c], srb + t_hi * drb)

    # 3. the row span in the column: floor over the y interval; an open upper end
    #    on an integer y excludes that row.
    up = drb >= 0
    y_top = np.where(up, y_hi, y_lo)
    y_bot = np.where(up, y_lo, y_hi)
    top_open = np.where(up, open_hi, open_lo)
    r_min = np.floor(y_bot)
    r_max = np.where(top_open, np.ceil(y_top) - 1.0, np.floor(y_top))
    r_max = np.maximum(r_max, r_min).astype(np.int64)
    r_min = r_min.astype(np.int64)

    # 4. expand the spans into cells, in travel order within each column:
    #    row = first_row + sign * (position within the span)
    nrow = r_max - r_min + 1
    sign = np.where(up, 1, -1)
    offset = np.cumsum(nrow) - nrow  # index of each span's first cell in the output
    cells = np.empty((int(nrow.sum()), 2), dtype=np.int64)
    cells[:, 0] = np.repeat(np.where(up, r_min, r_max) - sign * offset, nrow)
    cells[:, 0] += np.arange(cells.shape[0]) * np.repeat(sign, nrow)
    cells[:, 1] = np.repeat(col, nrow)
    return cells, np.repeat(beam_c, nrow)


def _beam_ends(ranges, angles, rmin, rmax, laser_pose):
    """World ends of the hit and no-return beams: ``(ends (M, 2), is_hit (M,))``."""
    hit, no_return = _beam_kinds(ranges, rmin, rmax)
    used = hit | no_return
    r = np.where(hit, ranges, rmax)[used]
    a = angles[used] + laser_pose[2]
    ends = laser_pose[:2] + r[:, None] * np.stack([np.cos(a), np.sin(a)], -1)
    return ends, hit[used]


def counting_map_update(hits, visits, scan, pose, grid):
    r"""Integrate one scan into the counting map (seed 004, the simple counting algorithm).

    Every cell keeps two counters: ``visits``, how many beams passed through
    or ended in it, and ``hits``, how many beams ended in it. The map is

    .. math:: p(m_i) \approx \frac{\mathrm{hits}_i}{\mathrm{visits}_i},

    the frequency with which a beam that reached cell ``i`` was reflected
    there (the "reflection map" of Probabilistic Robotics, section 9.2).
    For each beam from the laser at ``pose``:

    * a **hit** (``range_min <= r < range_max``, finite): every cell of
      :func:`beam_cells` from the laser to the endpoint gets a visit, and the
      endpoint's cell (the last one) a hit as well;
    * a **no-return** beam (``+inf`` or ``r >= range_max``): the cells up to
      ``range_max`` get a visit and no cell a hit: free space, no obstacle;
    * an **invalid** beam (NaN, ``<= 0``, ``< range_min``): ignored.

    A cell counts at most once per beam, and many times per scan if several
    beams cross it. Cells outside the grid are dropped. Cells no beam reaches
    keep their counts exactly.

    Parameters
    ----------
    hits, visits : array_like, shape grid.shape
        Counts so far (non-negative; not modified).
    scan : dict
        ``ranges`` (B,), ``angles`` (B,), ``range_min``, ``range_max``.
    pose : array_like, shape (3,)
        The **laser's** pose in the map frame, ``compose(robot_pose, laser_offset)``.
    grid : robolab.maps.OccupancyGrid
        The map's geometry (shape, resolution, origin); its cell values are not used.

    Returns
    -------
    hits, visits : numpy.ndarray of float, shape grid.shape
        New arrays with this scan's counts added; ``hits <= visits`` holds
        cell by cell whenever it held before.
    """
    grid = _check_grid(grid)
    hits = _layer("hits", hits, grid, counts=True)
    visits = _layer("visits", visits, grid, counts=True)
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser = _pose("pose", pose)
    ends, is_hit = _beam_ends(ranges, angles, rmin, rmax, laser)
    if ends.shape[0] == 0:
        return hits, visits
    start = grid.world_to_map(laser[:2])[::-1]
    cells, beam = beam_cells(start, grid.world_to_map(ends)[:, ::-1])
    # Counts are added on the crossed cells only (np.add.at sums repeated cells), so an
    # update costs in proportion to the beams' cells, not to the map (beyond the copy).
    # On the flat (C-ordered, see _layer) view: np.add.at's fast path takes one index array,
    # eight times faster than a (rows, cols) pair, with the same sums.
    width = grid.shape[1]
    inside = grid.contains_cell(cells)
    np.add.at(visits.reshape(-1), cells[inside, 0] * width + cells[inside, 1], 1.0)
    end_cells = grid.world_to_cell(ends[is_hit])  # the last cell of each hit beam
    ok = grid.contains_cell(end_cells)
    np.add.at(hits.reshape(-1), end_cells[ok, 0] * width + end_cells[ok, 1], 1.0)
    return hits, visits


def occupancy_from_counts(hits, visits):
    r"""The counting map: occupancy ``hits / visits``, unknown (-1) where no beam came.

    .. math::

        m_i = \begin{cases} \mathrm{hits}_i / \mathrm{visits}_i & \mathrm{visits}_i > 0 \\
                             -1 \ (\text{unknown}) & \mathrm{visits}_i = 0 \end{cases}

    Parameters
    ----------
    hits, visits : array_like, same shape
        Non-negative counts with ``hits <= visits``.

    Returns
    -------
    numpy.ndarray of float, same shape
        Values in [0, 1], or -1 (:data:`robolab.maps.UNKNOWN`) for never-visited
        cells: ready for ``grid.with_data(...)``.

    Raises
    ------
    ValueError
        Negative or non-finite counts, ``hits`` and ``visits`` of different shapes,
        or more hits than visits in a cell (a hit is also a visit).
    """
    h = as_array("hits", hits, finite=True, nonnegative=True)
    v = as_array("visits", visits, shape=h.shape, finite=True, nonnegative=True)
    if np.any(h > v):
        raise ValueError("hits must not exceed visits in any cell (a hit is also a visit)")
    out = np.full(h.shape, UNKNOWN)
    seen = v > 0
    out[seen] = h[seen] / v[seen]
    return out


def clip_map(occupancy, threshold=0.5):
    r"""Clip an occupancy map to 0 / 1 at ``threshold`` (the seed's clipping); unknown stays -1.

    .. math::

        \hat m_i = \begin{cases} 1 & m_i \ge \tau \\ 0 & 0 \le m_i < \tau \\
                                  -1 & m_i = -1 \ (\text{unknown}) \end{cases}

    A value exactly at the threshold counts as occupied, as in
    :attr:`robolab.maps.OccupancyGrid.occupied`.

    Parameters
    ----------
    occupancy : array_like
        Occupancy in [0, 1], or -1 for unknown cells.
    threshold : float
        ``tau`` in [0, 1] (default 0.5).

    Returns
    -------
    numpy.ndarray of float, same shape
        Values in {-1, 0, 1}.

    Raises
    ------
    ValueError
        An occupancy outside [0, 1] other than -1 (unknown), a NaN, or a
        ``threshold`` outside [0, 1].
    """
    m = as_array("occupancy", occupancy, finite=True)
    known = m != UNKNOWN
    if np.any((m[known] < 0) | (m[known] > 1)):
        raise ValueError("occupancy values must be in [0, 1] or -1 (unknown)")
    tau = check_positive("threshold", threshold, allow_zero=True)
    if tau > 1:
        raise ValueError(f"threshold must be in [0, 1], got {threshold!r}")
    return np.where(known, (m >= tau).astype(float), UNKNOWN)


def _sensor_model_params(params, resolution):
    """Checked parameters; ``alpha`` in metres (from ``alpha`` or ``alpha_cells * resolution``)."""
    if not isinstance(params, Mapping):
        raise TypeError(
            f"inverse_sensor_model_params must be a dict with l_occ, l_free, l_0, alpha, beta, "
            f"got {type(params).__name__}"
        )
    if "alpha" in params and "alpha_cells" in params:
        raise ValueError(
            "inverse_sensor_model_params has both alpha (metres) and alpha_cells (cells): "
            "give one obstacle thickness"
        )
    if "alpha_cells" in params:
        cells = check_positive("inverse_sensor_model_params['alpha_cells']", params["alpha_cells"])
        params = {**params, "alpha": cells * resolution}
    keys = ("l_occ", "l_free", "l_0", "alpha", "beta")
    missing = [k for k in keys if k not in params]
    if missing:
        raise ValueError(f"inverse_sensor_model_params lacks {', '.join(missing)}")
    out = {}
    for k in ("l_occ", "l_free", "l_0"):
        try:
            out[k] = float(params[k])
        except (TypeError, ValueError) as exc:
            raise TypeError(f"inverse_sensor_model_params[{k!r}] must be a number") from exc
        if not np.isfinite(out[k]):
            raise ValueError(
                f"inverse_sensor_model_params[{k!r}] must be finite, got {params[k]!r}"
            )
    for k in ("alpha", "beta"):
        out[k] = check_positive(f"inverse_sensor_model_params[{k!r}]", params[k])
    return out


def logodds_update(logodds, scan, pose, grid, inverse_sensor_model_params):
    r"""One step of occupancy grid mapping in log-odds form (Probabilistic Robotics, Table 9.1).

    For every cell :math:`m_i` in the perceptual field of the scan,

    .. math:: l_{t,i} = l_{t-1,i} + \mathrm{inverse\_sensor\_model}(m_i, x_t, z_t) - l_0 ,

    and other cells keep their value. The inverse range sensor model is Table
    9.2: with :math:`(x_i, y_i)` the centre of cell ``i`` and :math:`(x, y, \theta)`
    the laser pose,

    .. math::

        r &= \sqrt{(x_i - x)^2 + (y_i - y)^2}, \qquad
        \phi = \mathrm{wrap}(\operatorname{atan2}(y_i - y, x_i - x) - \theta) \\
        k &= \operatorname{argmin}_j |\mathrm{wrap}(\phi - \theta_j)| \\
        &\text{if } r > \min(z_{max}, z_k + \alpha/2) \text{ or } |\phi - \theta_k| > \beta/2:
            \ l_0 \ \text{(no information)} \\
        &\text{else if } z_k < z_{max} \text{ and } |r - z_k| < \alpha/2: \ l_{occ} \\
        &\text{else if } r \le z_k: \ l_{free}

    with :math:`z_{max}` = ``scan['range_max']``. A no-return beam (``+inf`` or
    ``r >= range_max``) is a reading :math:`z_k = z_{max}`: free up to the max
    range, never occupied. Invalid beams (NaN, ``<= 0``, ``< range_min``) are
    removed before the nearest-beam search. The evidence a scan adds does not
    depend on the map, so updates commute: the result after several scans is
    the prior plus the sum of each scan's evidence, in any order.

    Parameters
    ----------
    logodds : array_like, shape grid.shape
        Current log-odds :math:`l_{t-1}` (finite; not modified).
    scan : dict
        ``ranges`` (B,), ``angles`` (B,), ``range_min``, ``range_max``.
    pose : array_like, shape (3,)
        The **laser's** pose in the map frame.
    grid : robolab.maps.OccupancyGrid
        The map's geometry.
    inverse_sensor_model_params : dict
        ``l_occ``, ``l_free``, ``l_0`` (log-odds), ``alpha`` (obstacle thickness,
        metres, > 0) **or** ``alpha_cells`` (the thickness in cells of ``grid``,
        > 0: the same wall thickness in cells on a 2 cm and a 5 cm map),
        ``beta`` (beam width, radians, > 0); see :data:`INVERSE_SENSOR_MODEL`.

    Returns
    -------
    numpy.ndarray of float, shape grid.shape
        The updated log-odds :math:`l_t`, a new array.

    Raises
    ------
    ValueError
        ``logodds`` not of ``grid.shape`` or not finite, ``pose`` not three numbers,
        a missing key of ``inverse_sensor_model_params`` (or both ``alpha`` and
        ``alpha_cells``), ``alpha``, ``alpha_cells`` or ``beta`` <= 0.
    """
    grid = _check_grid(grid)
    out = _layer("logodds", logodds, grid)
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser = _pose("pose", pose)
    p = _sensor_model_params(inverse_sensor_model_params, grid.resolution)
    hit, no_return = _beam_kinds(ranges, rmin, rmax)
    used = hit | no_return
    if not np.any(used):
        return out
    z = np.where(hit, ranges, rmax)[used]
    beam_angles = wrap_angle(angles[used])
    order = np.argsort(beam_angles, kind="stable")
    beam_angles, z, can_hit = np.atleast_1d(beam_angles[order]), z[order], hit[used][order]

    # the cells that can be in the perceptual field: a disc of radius z_max + alpha/2
    reach = min(rmax, float(z.max()) + p["alpha"] / 2) / grid.resolution + 1.0
    centre = grid.world_to_map(laser[:2])  # (col, row), rotation-invariant disc
    lo = np.maximum(np.floor(centre - reach).astype(int), 0)
    hi = np.minimum(np.ceil(centre + reach).astype(int), [grid.shape[1], grid.shape[0]])
    if np.any(hi <= lo):
        return out
    # cell centres, separably: x = ox + cos(yaw) u - sin(yaw) v, y = oy + sin(yaw) u + cos(yaw) v
    u = ((np.arange(lo[0], hi[0]) + 0.5) * grid.resolution)[None, :]
    v = ((np.arange(lo[1], hi[1]) + 0.5) * grid.resolution)[:, None]
    c, s = np.cos(grid.origin[2]), np.sin(grid.origin[2])
    dx = (grid.origin[0] - laser[0]) + c * u - s * v
    dy = (grid.origin[1] - laser[1]) + s * u + c * v
    r = np.hypot(dx, dy)
    # only cells within reach can be in the perceptual field (the others get delta = 0):
    # the bearings and the beam search, the costly part, run on those cells only
    near = r <= min(rmax, float(z.max()) + p["alpha"] / 2)
    r, dx, dy = r[near], dx[near], dy[near]
    phi = wrap_angle(np.arctan2(dy, dx) - laser[2])

    # nearest beam in bearing, on the circle: the sorted angles padded by one beam
    # on each side (shifted by 2 pi) so that both neighbours of phi are at hand
    n = beam_angles.size
    padded = np.concatenate(
        [beam_angles[-1:] - 2 * np.pi, beam_angles, beam_angles[:1] + 2 * np.pi]
    )
    i = np.searchsorted(beam_angles, phi)  # padded[i] <= phi < padded[i + 1]
    d_left = phi - padded[i]
    d_right = padded[i + 1] - phi
    k = np.where(d_left <= d_right, (i - 1) % n, i % n)
    dphi = np.minimum(d_left, d_right)
    zk = z[k]

    in_field = (r <= np.minimum(rmax, zk + p["alpha"] / 2)) & (dphi <= p["beta"] / 2)
    occupied = in_field & can_hit[k] & (np.abs(r - zk) < p["alpha"] / 2)
    free = in_field & ~occupied & (r <= zk)
    delta = np.where(occupied, p["l_occ"] - p["l_0"], np.where(free, p["l_free"] - p["l_0"], 0.0))
    window = out[lo[1] : hi[1], lo[0] : hi[0]]
    window[near] += delta
    return out


def logodds_to_probability(logodds):
    r"""Occupancy probability from log-odds (Probabilistic Robotics, Table 9.1, last line).

    .. math:: p(m_i) = 1 - \frac{1}{1 + \exp(l_i)}

    computed stably (no overflow for large ``|l|``; ``l = +-inf`` gives 1 / 0).

    Parameters
    ----------
    logodds : array_like
        Log-odds, any shape; NaN is rejected.

    Returns
    -------
    numpy.ndarray of float, same shape
        Probabilities in [0, 1]; 0.5 where the log-odds are 0.

    Notes
    -----
    A cell no beam reached keeps the prior (0 here, p = 0.5), and an
    :class:`~robolab.maps.OccupancyGrid` counts ``p >= 0.5`` as occupied: to make a
    map, use :func:`robolab.maps.from_logodds`, which marks such cells unknown.
    """
    l = as_array("logodds", logodds)  # noqa: E741
    if np.any(np.isnan(l)):
        raise ValueError("logodds must not contain NaN")
    return expit(l)
