# ruff: noqa: F841, E501 -- a student mistake leaves a variable unused; lines as the student wrote them
"""Cells treated as closed squares: a beam crossing a column at an integer row also gets the row
above (extra corner cells).

Boundary values of a validity interval (half-open cells).

class: boundary
"""

import numpy as np

from robolab.validation import as_array


def beam_cells(start_cell, end_cell):
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
    top_open = np.zeros_like(up)
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
