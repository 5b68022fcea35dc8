"""Unseen cells are unknown, not walls: log-odds maps, ray casting and the likelihood field.

A log-odds map starts at the prior (0, p = 0.5) and an OccupancyGrid counts
``p >= 0.5`` as occupied, so converting the log-odds cell by cell makes every unseen
cell a wall. :func:`robolab.maps.from_logodds` marks them unknown (-1); unknown is
neither free nor occupied, ray casting passes through it and the likelihood field
measures distances to occupied cells only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robolab.geometry import compose
from robolab.maps import UNKNOWN, OccupancyGrid, from_logodds
from robolab.raycast import cast_rays
from solutions.mcl import likelihood_field
from solutions.odometry_mapping import INVERSE_SENSOR_MODEL, logodds_to_probability, logodds_update

OLIN = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "olin_ac109_1"


def _one_wall_map():
    """A 4 x 4 m map at 5 cm, prior everywhere, one scan's evidence of a wall at x = 3 m."""
    grid = OccupancyGrid(np.zeros((80, 80)), 0.05)
    angles = np.deg2rad(np.arange(-30.0, 31.0, 1.0))
    laser = np.array([1.0, 2.0, 0.0])
    scan = {"ranges": 2.0 / np.cos(angles), "angles": angles, "range_min": 0.1, "range_max": 8.0}
    lo = logodds_update(np.zeros(grid.shape), scan, laser, grid, INVERSE_SENSOR_MODEL)
    return grid, lo, laser


def test_from_logodds_marks_unseen_cells_unknown_and_keeps_seen_probabilities():
    grid, lo, _ = _one_wall_map()
    m = from_logodds(lo, grid)
    seen = lo != 0
    assert np.all(m.data[~seen] == UNKNOWN)
    np.testing.assert_allclose(m.data[seen], logodds_to_probability(lo[seen]))
    assert not np.any(m.occupied & m.unknown) and not np.any(m.free & m.unknown)
    # an explicit observed mask wins over the prior test
    mask = np.zeros(grid.shape, dtype=bool)
    mask[0, 0] = True
    only = from_logodds(np.zeros(grid.shape), grid, observed=mask)
    assert only.data[0, 0] == 0.5 and np.sum(only.data == UNKNOWN) == mask.size - 1
    with pytest.raises(ValueError, match="observed"):
        from_logodds(lo, grid, observed=mask[:3])
    with pytest.raises(ValueError, match="NaN"):
        from_logodds(np.full(grid.shape, np.nan), grid)


def test_rays_cross_unknown_space_and_stop_at_the_seen_wall():
    grid, lo, laser = _one_wall_map()
    naive = grid.with_data(logodds_to_probability(lo))
    assert naive.occupied.mean() > 0.8  # the bug: unseen cells are walls
    assert np.all(cast_rays(naive, [0.3, 0.3, 0.0], [0.0], 8.0) == 0.0)  # from unseen space
    m = from_logodds(lo, grid)
    assert m.occupied.mean() < 0.05
    # from the laser, the beams the scan saw end at the wall (x = 3 m, within alpha)
    z = cast_rays(m, laser, [0.0, 0.2, -0.2], 8.0)[0]
    np.testing.assert_allclose(z * np.cos([0.0, 0.2, -0.2]), 2.0, atol=2 * grid.resolution)
    # from unseen space rays travel through unknown cells until the seen wall or the edge
    assert cast_rays(m, [0.3, 0.3, 0.0], [np.pi / 2], 8.0)[0, 0] == 8.0
    # the likelihood field measures distances to the seen wall only
    field = likelihood_field(m, 0.1, 2.0)
    row, col = m.world_to_cell([2.0, 2.0])
    assert field["distance"][row, col] == pytest.approx(1.0, abs=2.5 * grid.resolution)
    naive_field = likelihood_field(naive, 0.1, 2.0)
    assert naive_field["distance"][row, col] < 0.6  # the unseen "walls" beside the beams


@pytest.mark.skipif(not OLIN.is_dir(), reason="../shared/data/olin_ac109_1 not present")
def test_a_real_scan_maps_to_walls_where_it_hit_and_rays_find_them_again():
    from robolab.datasets import read_recording
    from robolab.maps import load_map

    rec = read_recording(OLIN / "ac109_1_demo.bag", scan_topic="/scan", truth="/map_pose")
    room = load_map(OLIN / "ac109_1.yaml")
    grid = room.with_data(np.zeros(room.shape))
    still = np.flatnonzero(rec.scans.stamps - rec.scans.stamps[0] < 10.0)  # standing still
    pose = compose(rec.truth[still[0]], rec.laser_pose)
    lo = np.zeros(grid.shape)
    for i in still[::5]:
        scan = {
            "ranges": rec.scans.ranges[i],
            "angles": rec.scans.angles,
            "range_min": rec.scans.range_min,
            "range_max": rec.scans.range_max,
        }
        lo = logodds_update(lo, scan, pose, grid, INVERSE_SENSOR_MODEL)
    naive = grid.with_data(logodds_to_probability(lo))
    m = from_logodds(lo, grid)
    assert naive.occupied.mean() > 0.9 and m.occupied.mean() < 0.01
    i = still[0]
    valid = rec.scans.valid[i]
    z = cast_rays(m, pose, rec.scans.angles[valid], rec.scans.range_max)[0]
    err = np.abs(z - rec.scans.ranges[i, valid])
    assert np.median(err) < 0.05  # the map gives back the ranges it was built from
    assert np.median(cast_rays(naive, pose, rec.scans.angles[valid], 5.0)) < 0.1
