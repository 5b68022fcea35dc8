"""No-return beams (inf, r >= range_max) are ignored instead of counted as visits up to range_max.

Inputs the notebook describes: no-return beams are free-space evidence.

class: boundary
"""

import numpy as np

from solutions.odometry_mapping import (
    _beam_ends,
    _check_grid,
    _layer,
    _pose,
    _scan_arrays,
    beam_cells,
)


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
    hits = _layer("hits", hits, grid)
    visits = _layer("visits", visits, grid)
    if np.any(hits < 0) or np.any(visits < 0):
        raise ValueError("hits and visits must be non-negative counts")
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser = _pose("pose", pose)
    ends, is_hit = _beam_ends(ranges, angles, rmin, rmax, laser)
    ends, is_hit = ends[is_hit], is_hit[is_hit]
    if ends.shape[0] == 0:
        return hits, visits
    start = grid.world_to_map(laser[:2])[::-1]
    cells, beam = beam_cells(start, grid.world_to_map(ends)[:, ::-1])
    inside = grid.contains_cell(cells)
    flat = np.ravel_multi_index((cells[inside, 0], cells[inside, 1]), grid.shape)
    visits += np.bincount(flat, minlength=visits.size).reshape(grid.shape)
    end_cells = grid.world_to_cell(ends[is_hit])  # the last cell of each hit beam
    ok = grid.contains_cell(end_cells)
    flat = np.ravel_multi_index((end_cells[ok, 0], end_cells[ok, 1]), grid.shape)
    hits += np.bincount(flat, minlength=hits.size).reshape(grid.shape)
    return hits, visits
