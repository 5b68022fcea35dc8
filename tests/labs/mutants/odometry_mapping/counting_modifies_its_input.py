"""No copy of the counts: the += updates modify the caller's hits and visits arrays and return
them.

In-place modification and aliasing.

class: aliasing
"""

import numpy as np

from solutions.odometry_mapping import _beam_ends, _check_grid, _pose, _scan_arrays, beam_cells


def counting_map_update(hits, visits, scan, pose, grid):
    grid = _check_grid(grid)
    hits = np.asarray(hits, dtype=float)
    visits = np.asarray(visits, dtype=float)
    if np.any(hits < 0) or np.any(visits < 0):
        raise ValueError("hits and visits must be non-negative counts")
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser = _pose("pose", pose)
    ends, is_hit = _beam_ends(ranges, angles, rmin, rmax, laser)
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
