"""Visible checks for lab 04, mapping with raw odometry (``notebooks/04_odometry_mapping.ipynb``).

Quick and friendly: a worked example, the shape, one invariant. The hidden
tests check much more (random beams against a brute-force supercover, Table
9.2 cell by cell, the bundled bag against the true floor plan).
"""

from __future__ import annotations

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_shape
from robolab.maps import OccupancyGrid

__all__ = [
    "check_scan_endpoints",
    "check_beam_cells",
    "check_counting_map_update",
    "check_occupancy_from_counts",
    "check_clip_map",
    "check_logodds_update",
    "check_logodds_to_probability",
]


def _scan(ranges, angles, range_min=0.05, range_max=4.0):
    return {
        "ranges": np.asarray(ranges, dtype=float),
        "angles": np.asarray(angles, dtype=float),
        "range_min": range_min,
        "range_max": range_max,
    }


def _grid(rows=6, cols=6, resolution=1.0):
    return OccupancyGrid(np.full((rows, cols), -1.0), resolution)


@check
def check_scan_endpoints(scan_endpoints):
    """Two beams from a robot at (1, 2) facing +y, a laser 0.1 m ahead; an inf and a NaN beam."""
    scan = _scan([2.0, 1.0, np.inf, np.nan], [0.0, np.pi / 2, 0.3, 0.6])
    pts = scan_endpoints(scan, np.array([1.0, 2.0, np.pi / 2]), np.array([0.1, 0.0, 0.0]))
    pts = np.asarray(pts, dtype=float)
    if pts.shape == (4, 2):
        raise CheckFailed(
            "the inf and NaN beams must not give endpoints: keep only range_min <= r < range_max"
        )
    expect_shape("scan_endpoints with two valid beams", pts, (2, 2))
    # laser at (1, 2.1) heading +y: beam 0 -> (1, 4.1), beam pi/2 -> (0, 2.1)
    expect_close(
        "endpoints (laser at (1, 2.1), heading +y)", pts, [[1.0, 4.1], [0.0, 2.1]], atol=1e-9
    )


@check
def check_beam_cells(beam_cells):
    """One beam along row 0, one diagonal beam; cells ordered from start to end."""
    cells, beam = beam_cells(np.array([0.5, 0.5]), np.array([[0.5, 3.5], [2.5, 1.7]]))
    cells = np.asarray(cells, dtype=float)
    beam = np.asarray(beam, dtype=float)
    if cells.ndim != 2 or cells.shape[1] != 2 or beam.shape != (cells.shape[0],):
        raise CheckFailed(
            f"expected cells (N, 2) and beam (N,), got {cells.shape} and {beam.shape}"
        )
    expect_close(
        "cells of the beam (0.5, 0.5) -> (0.5, 3.5)",
        cells[beam == 0],
        [[0, 0], [0, 1], [0, 2], [0, 3]],
    )
    # (0.5, 0.5) -> (2.5, 1.7): p = (0.5 + 2t, 0.5 + 1.2t) crosses row 1 at t = 0.25 (col 0.8)
    # and col 1 at t = 5/12 (row 1.33), then row 2 at t = 0.75 (col 1.4)
    expect_close(
        "cells of the beam (0.5, 0.5) -> (2.5, 1.7)",
        cells[beam == 1],
        [[0, 0], [1, 0], [1, 1], [2, 1]],
    )


@check
def check_counting_map_update(counting_map_update):
    """A single hit beam and a no-return beam on a 1 m grid."""
    grid = _grid()
    scan = _scan([3.2, np.inf], [0.0, np.pi / 2])
    hits, visits = counting_map_update(
        np.zeros((6, 6)), np.zeros((6, 6)), scan, np.array([0.5, 0.5, 0.0]), grid
    )
    hits = expect_shape("hits", hits, (6, 6))
    visits = expect_shape("visits", visits, (6, 6))
    expected_visits = np.zeros((6, 6))
    expected_visits[0, :4] += 1
    expected_visits[:5, 0] += 1
    expected_hits = np.zeros((6, 6))
    expected_hits[0, 3] = 1
    expect_close("hits (one hit at the endpoint (3.7, 0.5), cell (0, 3))", hits, expected_hits)
    expect_close(
        "visits ((0, 0)..(0, 3): the hit beam; (0, 0)..(4, 0): the inf beam, up to range_max)",
        visits,
        expected_visits,
    )
    if np.any(hits > visits):
        raise CheckFailed("a hit must also count as a visit")


@check
def check_occupancy_from_counts(occupancy_from_counts):
    """hits / visits, and -1 where no beam came."""
    got = occupancy_from_counts(np.array([0.0, 1.0, 2.0]), np.array([0.0, 4.0, 2.0]))
    expect_close("occupancy_from_counts([0, 1, 2], [0, 4, 2])", got, [-1.0, 0.25, 1.0])


@check
def check_clip_map(clip_map):
    """Clipping at 0.5: unknown stays unknown."""
    got = clip_map(np.array([-1.0, 0.1, 0.5, 0.9]))
    expect_close("clip_map([-1, 0.1, 0.5, 0.9])", got, [-1.0, 0.0, 1.0, 1.0])


@check
def check_logodds_update(logodds_update):
    """One beam along a row of cells: free, then occupied around the range, then untouched."""
    grid = _grid(1, 10, 0.5)
    params = {"l_occ": 2.0, "l_free": -1.0, "l_0": 0.0, "alpha": 0.6, "beta": 0.2}
    got = logodds_update(
        np.zeros((1, 10)), _scan([3.0], [0.0], 0.05, 4.5), np.array([0.0, 0.25, 0.0]), grid, params
    )
    got = expect_shape("logodds_update result", got, (1, 10))
    # cell centres at x = 0.25, 0.75, ..., 4.75: free up to 2.25, occupied where |r - 3| < 0.3
    expect_close(
        "log-odds along the beam (range 3 m, alpha 0.6 m)",
        got[0],
        [-1, -1, -1, -1, -1, 2, 2, 0, 0, 0],
    )
    twice = logodds_update(
        got, _scan([3.0], [0.0], 0.05, 4.5), np.array([0.0, 0.25, 0.0]), grid, params
    )
    expect_close("a second identical scan adds the same evidence again", twice, 2 * got)


@check
def check_logodds_to_probability(logodds_to_probability):
    """0 -> 0.5, log 3 -> 0.75, and no overflow for large log-odds."""
    got = logodds_to_probability(np.array([0.0, np.log(3.0), -np.log(3.0)]))
    expect_close("logodds_to_probability([0, log 3, -log 3])", got, [0.5, 0.75, 0.25])
    big = np.asarray(logodds_to_probability(np.array([-1000.0, 1000.0])), dtype=float)
    if not np.all(np.isfinite(big)):
        raise CheckFailed(
            "log-odds of +-1000 must give probabilities 0 and 1, not NaN: avoid exp overflow"
        )
