"""The inverse sensor model's wall thickness follows the map's resolution.

``alpha`` is in metres in the lab's exercise signature; the default parameters
give it in cells (``alpha_cells``), so a 2 cm map gets walls as many cells thick as
a 5 cm map, not five cells where the 5 cm map has two.
"""

from __future__ import annotations

import numpy as np
import pytest

from robolab.maps import OccupancyGrid
from solutions.odometry_mapping import INVERSE_SENSOR_MODEL, logodds_update

SCAN = {"ranges": np.array([1.5]), "angles": np.array([0.0]), "range_min": 0.1, "range_max": 5.0}


def _occupied_run(params, resolution):
    """Cells along one beam hitting a wall 1.5 m ahead that the update marks occupied."""
    n = int(round(4.0 / resolution))
    grid = OccupancyGrid(np.zeros((n, n)), resolution, np.array([-1.5, -1.5, 0.0]))
    pose = np.array([-0.7 * resolution, 0.3 * resolution, 0.0])  # off the cell boundaries
    lo = logodds_update(np.zeros(grid.shape), SCAN, pose, grid, params)
    row = grid.world_to_cell(pose[:2])[0]
    return lo[row] > 0


@pytest.mark.parametrize("resolution", [0.01, 0.02, 0.05, 0.1])
def test_default_walls_are_two_cells_thick_at_any_resolution(resolution):
    occ = _occupied_run(INVERSE_SENSOR_MODEL, resolution)
    assert occ.sum() == 2
    # the same as alpha in metres scaled by hand
    metres = {k: v for k, v in INVERSE_SENSOR_MODEL.items() if k != "alpha_cells"}
    metres["alpha"] = INVERSE_SENSOR_MODEL["alpha_cells"] * resolution
    np.testing.assert_array_equal(occ, _occupied_run(metres, resolution))


def test_alpha_in_metres_still_works_and_is_fixed_in_metres():
    params = {k: v for k, v in INVERSE_SENSOR_MODEL.items() if k != "alpha_cells"}
    params["alpha"] = 0.1
    assert _occupied_run(params, 0.05).sum() == 2
    assert _occupied_run(params, 0.02).sum() == 5  # metres: more cells on a finer map


@pytest.mark.parametrize(
    "change, match",
    [
        ({"alpha": 0.1}, "both"),
        ({"alpha_cells": 0.0}, "alpha_cells"),
        ({"alpha_cells": -1.0}, "alpha_cells"),
    ],
)
def test_bad_thickness_parameters_raise(change, match):
    with pytest.raises(ValueError, match=match):
        _occupied_run({**INVERSE_SENSOR_MODEL, **change}, 0.05)
