"""The measurement-model lab's ray casting API, in pixel units: ``castrays``, ``castraysingle``.

The lab's original signatures take a sensor position in pixels and a bare occupancy
array (rows = y); both call :func:`robolab.raycast.cast_rays` on a pixel grid
(resolution 1, origin 0) cached per map object, and share its semantics.
"""

from __future__ import annotations

import weakref

import numpy as np

from robolab.maps import OccupancyGrid
from robolab.validation import as_array, check_finite, check_positive

__all__ = ["castrays", "castraysingle"]

# id(map) -> (weak reference to map, pixel grid). Arrays are unhashable, hence
# keyed by id and checked through the weak reference; a few entries suffice.
_PIXEL_GRIDS: dict[int, tuple[weakref.ref, OccupancyGrid]] = {}
_PIXEL_GRIDS_MAX = 8


def _pixel_grid(map) -> OccupancyGrid:  # noqa: A002 - the lab's argument name
    """``map`` as an OccupancyGrid of resolution 1 with origin 0, reusing a cached one.

    The pixel grid is cached per map object (weakly), so that calling the lab
    functions in a loop does not rebuild the distance field every time.
    """
    if isinstance(map, OccupancyGrid):
        if map.resolution == 1.0 and not np.any(map.origin):
            return map
        data, threshold = map.data, map.occupied_threshold
    elif isinstance(map, np.ndarray):
        data, threshold = map, 0.5
        if map.ndim != 2:
            raise ValueError(
                f"map must be a 2D occupancy array (rows = y, columns = x), got shape {map.shape}"
            )
    else:  # lists and the like: not weak-referenceable, convert on every call
        return OccupancyGrid(as_array("map", map, ndim=2), 1.0)
    data = as_array("map", data, ndim=2)
    entry = _PIXEL_GRIDS.get(id(map))
    if entry is not None and entry[0]() is map and np.array_equal(entry[1].data, data):
        return entry[1]
    grid = OccupancyGrid(data.copy(), 1.0, occupied_threshold=threshold)
    if len(_PIXEL_GRIDS) >= _PIXEL_GRIDS_MAX:
        _PIXEL_GRIDS.clear()
    _PIXEL_GRIDS[id(map)] = (weakref.ref(map), grid)
    return grid


def castrays(xc, yc, thetas, map, lidarrange) -> np.ndarray:  # noqa: A002
    """Ranges in pixels of several beams from one sensor position (the lab's ``castrays``).

    Parameters
    ----------
    xc, yc : float
        Sensor position in continuous pixel coordinates: pixel ``(row j, col i)``
        covers ``[i, i + 1) x [j, j + 1)``, so its centre is ``(i + 0.5, j + 0.5)``;
        x runs along columns, y along rows.
    thetas : array_like, shape (B,)
        Beam directions in radians, counter-clockwise from +x (absolute, not
        relative to a heading).
    map : OccupancyGrid or array_like, shape (H, W)
        Occupancy, 1/True = obstacle, in the grid convention ``map[row = y, col = x]``
        with row 0 at the bottom (``load_map("maze.png").data``, or
        ``numpy.flipud`` of an image-ordered mask). A grid's resolution and origin
        are ignored: everything is in pixels from the corner of cell (0, 0).
    lidarrange : float
        Sensor range in pixels, > 0.

    Returns
    -------
    numpy.ndarray, shape (B,)
        Range of each beam in pixels, with the semantics of :func:`cast_rays`.
    """
    grid = _pixel_grid(map)
    xc = check_finite("xc", xc)
    yc = check_finite("yc", yc)
    thetas = as_array("thetas", thetas, ndim=(0, 1), finite=True).reshape(-1)
    from robolab.raycast import cast_rays  # robolab.raycast re-exports this module

    return cast_rays(grid, [xc, yc, 0.0], thetas, check_positive("lidarrange", lidarrange))[0]


def castraysingle(xc, yc, theta, map, lidarrange) -> float:  # noqa: A002
    """Range in pixels of one beam (the lab's ``castraysingle``); see :func:`castrays`."""
    theta = check_finite("theta", theta)
    return float(castrays(xc, yc, [theta], map, lidarrange)[0])
