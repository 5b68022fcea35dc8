"""The office-like floor plan behind ``data/office.yaml`` and the simulated bags.

The building covers ``[0, 20] x [0, 12]`` metres in the map frame:

- a 2 m wide east-west corridor (``5.0 <= y <= 7.0``) with a cabinet and a
  bench that break its symmetry;
- four **identical** offices north of the corridor, one every 5 m, each with
  the same door, desk, table and cabinet, so that a robot that wakes up in one
  of them cannot tell which one it is in until it has seen the corridor
  (global localization is ambiguous at first, lab 05);
- south of the corridor an open-plan room with two pillars, a meeting room
  with a large table, and two small rooms that differ in their furniture.

Walls are 0.2 m thick (4 cells at the default 5 cm resolution), so that no ray
slips between two occupied cells. Outside the outer walls the map is unknown
(``-1``), as in a map made by a SLAM package. Everything is drawn from a list
of axis-aligned rectangles, so the map is exactly reproducible.
"""

from __future__ import annotations

import numpy as np

from robolab.maps import UNKNOWN, OccupancyGrid
from robolab.validation import check_positive

__all__ = ["office_floorplan", "OFFICE_SIZE", "OFFICE_ORIGIN", "WALL_THICKNESS", "TOP_ROOM_X"]

#: Width and height of the building, metres (outer wall centre lines).
OFFICE_SIZE = (20.0, 12.0)
#: World pose of the map's lower-left corner: a 0.5 m unknown margin around the building.
OFFICE_ORIGIN = (-0.5, -0.5, 0.0)
#: Thickness of every wall, metres.
WALL_THICKNESS = 0.2
#: Left edges (wall centre lines) of the four identical offices north of the corridor.
TOP_ROOM_X = (0.0, 5.0, 10.0, 15.0)

_H = WALL_THICKNESS / 2.0
_MARGIN = 0.5

# Rectangles (x0, x1, y0, y1) in metres. Walls are given by their centre line
# and expanded by half the wall thickness.
_CORRIDOR = (5.0 - _H, 7.0 + _H)  # centre lines of the corridor's walls: y = 4.9 and y = 7.1


def _walls() -> list[tuple[float, float, float, float]]:
    w, h = OFFICE_SIZE
    rects = [
        # outer walls
        (-_H, w + _H, -_H, _H),
        (-_H, w + _H, h - _H, h + _H),
        (-_H, _H, -_H, h + _H),
        (w - _H, w + _H, -_H, h + _H),
        # corridor walls (free corridor: 5.0 <= y <= 7.0)
        (0.0, w, 4.8, 5.0),
        (0.0, w, 7.0, 7.2),
    ]
    # dividers between the four identical north offices
    rects += [(x - _H, x + _H, 7.0, h) for x in TOP_ROOM_X[1:]]
    # dividers between the south rooms: open plan | meeting | small | small
    rects += [(x - _H, x + _H, 0.0, 5.0) for x in (8.0, 14.0, 17.0)]
    return rects


def _doors() -> list[tuple[float, float, float, float]]:
    """Openings cut through the corridor walls (1 m wide, the open plan's 1.5 m)."""
    north = [(x0 + 1.0, x0 + 2.0, 6.9, 7.3) for x0 in TOP_ROOM_X]
    south = [
        (3.0, 4.5, 4.7, 5.1),
        (12.2, 13.2, 4.7, 5.1),
        (14.6, 15.6, 4.7, 5.1),
        (18.4, 19.4, 4.7, 5.1),
    ]
    return north + south


def _furniture() -> list[tuple[float, float, float, float]]:
    rects = []
    for x0 in TOP_ROOM_X:  # the same furniture in every north office
        rects += [
            (x0 + 2.6, x0 + 4.6, 11.1, 11.9),  # desk against the back wall
            (x0 + 2.8, x0 + 3.6, 8.6, 9.4),  # small square table
            (x0 + 0.1, x0 + 0.7, 9.0, 10.6),  # cabinet against the west wall
        ]
    rects += [
        # open-plan room: two pillars and a row of desks
        (2.3, 2.7, 2.2, 2.6),
        (5.3, 5.7, 2.2, 2.6),
        (0.1, 1.7, 0.1, 0.9),
        (5.9, 7.9, 0.1, 0.7),
        # meeting room: a large table
        (9.6, 12.4, 1.6, 3.2),
        # small room west: shelf along the south wall
        (14.1, 16.0, 0.1, 0.5),
        # small room east: an L-shaped desk
        (18.6, 19.9, 0.1, 1.5),
        (19.3, 19.9, 1.5, 3.0),
        # corridor: a cabinet against the north wall and a bench against the south wall
        (7.6, 8.6, 6.7, 7.0),
        (15.8, 17.4, 5.0, 5.3),
    ]
    return rects


def _fill(data: np.ndarray, rect, value: float, resolution: float) -> None:
    """Set every cell whose centre lies inside ``rect`` (world metres) to ``value``."""
    x0, x1, y0, y1 = rect
    ox, oy = OFFICE_ORIGIN[0], OFFICE_ORIGIN[1]
    # cell i covers [o + i r, o + (i + 1) r); its centre is inside [a, b) when
    # i in [ceil((a - o)/r - 0.5), ceil((b - o)/r - 0.5)).
    c0, c1 = (int(np.ceil((v - ox) / resolution - 0.5 - 1e-9)) for v in (x0, x1))
    r0, r1 = (int(np.ceil((v - oy) / resolution - 0.5 - 1e-9)) for v in (y0, y1))
    data[max(r0, 0) : max(r1, 0), max(c0, 0) : max(c1, 0)] = value


def office_floorplan(resolution: float = 0.05) -> OccupancyGrid:
    """Draw the office floor plan as an occupancy grid.

    Parameters
    ----------
    resolution : float
        Cell size in metres (default 0.05). Must leave walls at least two cells
        thick, i.e. ``resolution <= 0.1``.

    Returns
    -------
    OccupancyGrid
        Values 1 (wall or furniture), 0 (free) and -1 (unknown, outside the
        building); origin :data:`OFFICE_ORIGIN`, size 21 m x 13 m.

    Raises
    ------
    ValueError
        If ``resolution`` is not positive or too coarse for 2-cell walls.

    Examples
    --------
    >>> grid = office_floorplan()
    >>> grid.shape
    (260, 420)
    """
    resolution = check_positive("resolution", resolution)
    if WALL_THICKNESS / resolution < 2.0 - 1e-9:
        raise ValueError(
            f"resolution must be <= {WALL_THICKNESS / 2} m so that walls are >= 2 cells thick, "
            f"got {resolution}"
        )
    w, h = OFFICE_SIZE
    cols = int(round((w + 2 * _MARGIN) / resolution))
    rows = int(round((h + 2 * _MARGIN) / resolution))
    data = np.full((rows, cols), UNKNOWN)
    _fill(data, (0.0, w, 0.0, h), 0.0, resolution)
    for rect in _walls():
        _fill(data, rect, 1.0, resolution)
    for rect in _doors():
        _fill(data, rect, 0.0, resolution)
    for rect in _furniture():
        _fill(data, rect, 1.0, resolution)
    return OccupancyGrid(data, resolution, np.asarray(OFFICE_ORIGIN, dtype=float))
