"""Visible checks for lab 06, EKF localization with grid mapping.

Quick and friendly: shapes, one worked example and one invariant per exercise.
The hidden tests are stronger (finite differences at random states, a
brute-force ray march, a cell-by-cell inverse sensor model, a hand-written EKF,
the bundled run).
"""

from __future__ import annotations

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_shape
from robolab.maps import OccupancyGrid

__all__ = [
    "check_transition_model",
    "check_state_jacobian",
    "check_measurement_function",
    "check_measurement_jacobian",
    "check_inverse_sensor_model",
    "check_update_map",
    "check_ekf_mapping_step",
]


def _wall_grid():
    """A 40 x 40 map with a wall whose face is at x = 30 (unit cells)."""
    d = np.zeros((40, 40))
    d[:, 30] = 1.0
    return OccupancyGrid(d, 1.0)


@check
def check_transition_model(transition_model):
    """Straight ahead, a turn that moves along the old heading, and heading wrapping."""
    out = expect_shape(
        "transition_model shape", transition_model(np.array([1.0, 2.0, 0.0]), 2.0, 0.0, 0.5), (3,)
    )
    expect_close("from (1, 2, 0) at speed 2 for 0.5 s", out, [2.0, 2.0, 0.0], atol=1e-9)
    out = np.asarray(transition_model(np.array([1.0, 2.0, np.pi / 2]), 2.0, 1.0, 0.5), dtype=float)
    expect_close(
        "facing +y, turning at 1 rad/s: moves along the OLD heading, then turns by 0.5",
        out,
        [1.0, 3.0, np.pi / 2 + 0.5],
        atol=1e-9,
    )
    out = np.asarray(transition_model(np.array([0.0, 0.0, 3.0]), 0.0, 2.0, 0.5), dtype=float)
    expect_close("heading 3 + 1 rad must wrap to [-pi, pi)", out[2], 4.0 - 2 * np.pi, atol=1e-9)


@check
def check_state_jacobian(state_jacobian):
    """The worked example: only the theta column differs from the identity."""
    G = expect_shape(
        "state_jacobian shape", state_jacobian(np.array([3.0, 4.0, 0.0]), 2.0, 0.7, 0.5), (3, 3)
    )
    expect_close(
        "G at theta = 0, speed 2, dt 0.5", G, [[1, 0, 0], [0, 1, 1.0], [0, 0, 1]], atol=1e-9
    )
    G = np.asarray(state_jacobian(np.array([3.0, 4.0, np.pi / 2]), 2.0, 0.7, 0.5), dtype=float)
    expect_close("G at theta = pi/2: dx/dtheta = -v sin(theta) dt", G[0, 2], -1.0, atol=1e-9)


@check
def check_measurement_function(measurement_function):
    """Facing a wall 10 units ahead; beams that leave the map read max range."""
    z = expect_shape(
        "measurement_function shape (36 beams)",
        measurement_function(np.array([20.0, 15.0, 0.0]), _wall_grid()),
        (36,),
    )
    expect_close("beam 0 faces the wall at x = 30 from x = 20", z[0], 10.0, atol=1e-6)
    expect_close(
        "beam 18 points backwards and leaves the map: max range 20", z[18], 20.0, atol=1e-6
    )
    expect_close(
        "beam 9 points to +y and leaves the map after 25 units: max range 20", z[9], 20.0, atol=1e-6
    )
    if np.any(z < 0) or np.any(z > 20):
        raise CheckFailed(f"ranges must lie in [0, max_range], got {z.min():.3g} .. {z.max():.3g}")


@check
def check_measurement_jacobian(measurement_jacobian):
    """Facing a wall squarely: moving forward shortens beam 0 one for one."""
    H = expect_shape(
        "measurement_jacobian shape (36 beams x 3)",
        measurement_jacobian(np.array([20.0, 15.0, 0.0]), _wall_grid()),
        (36, 3),
    )
    expect_close(
        "row 0 (beam 0 facing the wall): dr/dx = -1, dr/dy = 0, dr/dtheta = 0",
        H[0],
        [-1.0, 0.0, 0.0],
        atol=1e-4,
    )
    expect_close("beam 18 reads max range: its row is 0", H[18], [0.0, 0.0, 0.0], atol=1e-9)


@check
def check_inverse_sensor_model(inverse_sensor_model):
    """One beam along +x ending 5 cells ahead: free, then +1, then unreached."""
    out = expect_shape(
        "inverse_sensor_model shape",
        inverse_sensor_model(
            (20, 20),
            np.array([3.5, 10.5, 0.0]),
            np.array([5.0]),
            beam_angles=np.array([0.0]),
            beam_width=np.deg2rad(10.0),
        ),
        (20, 20),
    )
    expect_close(
        "cells the beam passes, row 10, columns 3..7", out[10, 3:8], np.full(5, -0.2), atol=1e-9
    )
    expect_close("the cell where the beam ends, row 10, column 8", out[10, 8], 1.0, atol=1e-9)
    expect_close("cells beyond the end, row 10, columns 9..", out[10, 9:], np.zeros(11), atol=1e-9)
    expect_close("a cell off the beam, row 12, column 6", out[12, 6], 0.0, atol=1e-9)


@check
def check_update_map(update_map):
    """The map accumulates: the same scan twice gives twice the values; far cells stay 0."""
    state, scan = np.array([20.5, 20.5, 0.0]), np.full(36, 3.0)
    once = expect_shape("update_map shape", update_map(np.zeros((40, 40)), state, scan), (40, 40))
    twice = np.asarray(update_map(once.copy(), state, scan), dtype=float)
    expect_close("twice the same scan = twice the values", twice, 2 * once, atol=1e-9)
    expect_close(
        "a cell 10 units away is not reached by 3-unit beams", once[20, 30], 0.0, atol=1e-9
    )
    expect_close("the cell 3 units ahead is where beam 0 ends", once[20, 23], 1.0, atol=1e-9)
    expect_close("the robot's own cell is free", once[20, 20], -0.2, atol=1e-9)


@check
def check_ekf_mapping_step(ekf_mapping_step):
    """A perfect scan in a known map keeps the estimate near the truth and shrinks P."""
    d = np.zeros((40, 40))
    d[[0, -1], :] = 1.0
    d[:, [0, -1]] = 1.0
    from robolab.raycast import cast_rays

    truth = np.array([20.1, 20.0, 0.0])  # where the robot is after moving 1 unit/s for 0.1 s
    scan = cast_rays(OccupancyGrid(d, 1.0), truth, np.deg2rad(10.0 * np.arange(36)), 20.0)[0]
    prior_map = np.where(d > 0, 3.0, -1.0)
    p0 = np.diag([0.09, 0.09, 0.01])
    out = ekf_mapping_step(
        (np.array([20.0, 20.0, 0.0]), p0, np.diag([1e-4, 1e-4, 1e-3]), np.eye(36)),
        prior_map,
        1.0,
        0.0,
        scan,
        0.1,
    )
    if not isinstance(out, tuple) or len(out) != 3:
        raise CheckFailed("ekf_mapping_step must return (state, covariance, map)")
    state = expect_shape("state", out[0], (3,))
    cov = expect_shape("covariance", out[1], (3, 3))
    new_map = expect_shape("map", out[2], (40, 40))
    expect_close("the estimate with a perfect scan", state, truth, atol=0.05)
    if not np.trace(cov) < np.trace(p0):
        raise CheckFailed(
            f"36 ranges should shrink the covariance: trace {np.trace(cov):.4g} "
            f">= {np.trace(p0):.4g}"
        )
    if np.array_equal(new_map, prior_map):
        raise CheckFailed("the map did not change: call update_map after the prediction")
