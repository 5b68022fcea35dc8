"""The EKF-mapping world of lab 06."""

from __future__ import annotations

import numpy as np

from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays_reference as cast_rays  # byte-identical data everywhere
from robolab.sim.motion import Controller, follow_route
from robolab.sim.run import _check_clearance
from robolab.sim.runs import SEEDS

# -- the EKF world of lab 06 ------------------------------------------------------
EKF_SIZE = 40
EKF_ZMAX = 20.0
EKF_DT = 0.1
EKF_N_BEAMS = 36
EKF_ROUTE = np.array([[30.0, 10.0], [30.0, 30.0], [10.0, 30.0], [10.0, 10.0], [30.0, 10.0]])
EKF_START = (10.0, 10.0, 0.0)
EKF_DURATION = 50.0
EKF_CONTROL_NOISE = (0.05, 0.02)  # std of executed speed (units/s) and rotation speed (rad/s)
EKF_SCAN_SIGMA = 0.2  # units
EKF_PROCESS_NOISE = np.diag([0.0001, 0.0001, 0.08])  # the lab's process noise
_EKF_BLOCKS = [  # (row0, row1, col0, col1): rows are y, cols are x
    (16, 24, 16, 24),  # the central block, inside the loop
    (20, 26, 3, 6),
    (33, 36, 12, 17),
    (12, 16, 34, 37),
    (3, 6, 24, 29),
    (34, 37, 31, 34),
    (4, 7, 4, 7),
]


def ekf_world() -> dict[str, np.ndarray]:
    """The simulated world of lab 06 as a dict of arrays.

    A 40 x 40 cell world (1 unit per cell, border walls and block obstacles)
    and a 50 s run of lab 06's unicycle transition model
    ``theta' = wrap(theta + rotation_speed dt)``, ``x' = x + speed cos(theta) dt``,
    ``y' = y + speed sin(theta) dt`` with ``dt = 0.1``, a loop around the
    central block. The executed velocities carry Gaussian noise
    (:data:`EKF_CONTROL_NOISE`); the recorded commands do not. After every step
    the 36-beam sensor (beam ``i`` at ``i * 10`` degrees from the heading,
    ``zmax = 20`` units, from the robot's position) measures the ray-cast
    range plus ``N(0, 0.2**2)``, clipped to ``[0, zmax]``; no obstacle within
    ``zmax`` reads exactly ``zmax``.

    Returns
    -------
    dict
        ``world (40, 40)`` occupancy 0/1 as ``world[row, col]`` with row = y
        (MATLAB code often indexes ``map(x, y)``: use ``world.T``); ``resolution``;
        ``dt``; ``zmax``; ``beam_angles (36,)`` rad; ``speed (S,)``,
        ``rotation_speed (S,)``; ``states (S + 1, 3)`` true ``(x, y, theta)``;
        ``scans (S, 36)`` measured after step ``k`` at ``states[k + 1]``;
        ``true_scans (S, 36)``; ``initial_state (3,)``; ``initial_cov (3, 3)``;
        ``process_noise (3, 3)``; ``scan_sigma``; ``control_noise (2,)``.
    """
    world = np.zeros((EKF_SIZE, EKF_SIZE))
    world[[0, -1], :] = 1.0
    world[:, [0, -1]] = 1.0
    for r0, r1, c0, c1 in _EKF_BLOCKS:
        world[r0:r1, c0:c1] = 1.0
    grid = OccupancyGrid(world, 1.0)
    rng = np.random.default_rng(SEEDS["ekf_world"])
    g_ctrl, g_scan = rng.spawn(2)
    ctrl = Controller(
        v_max=2.0,
        v_min=0.2,
        w_max=1.0,
        k_v=2.0,
        k_w=2.0,
        turn_threshold=0.3,
        tolerance=0.3,
        a_max=2.0,
        alpha_max=3.0,
    )
    states, cmds, _ = follow_route(
        EKF_ROUTE,
        EKF_START,
        duration=EKF_DURATION,
        dt=EKF_DT,
        controller=ctrl,
        model="euler",
        control_noise=EKF_CONTROL_NOISE,
        rng=g_ctrl,
    )
    _check_clearance(grid, np.arange(len(states)) * EKF_DT, states, 1.0)
    angles = np.deg2rad(10.0 * np.arange(EKF_N_BEAMS))
    true_scans = cast_rays(grid, states[1:], angles, EKF_ZMAX)
    scans = np.clip(
        true_scans + EKF_SCAN_SIGMA * g_scan.standard_normal(true_scans.shape), 0.0, EKF_ZMAX
    )
    scans[true_scans >= EKF_ZMAX] = EKF_ZMAX
    return {
        "world": world,
        "resolution": np.float64(1.0),
        "dt": np.float64(EKF_DT),
        "zmax": np.float64(EKF_ZMAX),
        "beam_angles": angles,
        "speed": cmds[:, 0].copy(),
        "rotation_speed": cmds[:, 1].copy(),
        "states": states,
        "scans": scans,
        "true_scans": true_scans,
        "initial_state": np.asarray(EKF_START, dtype=float),
        "initial_cov": np.diag([0.01, 0.01, 0.001]),
        "process_noise": EKF_PROCESS_NOISE.copy(),
        "scan_sigma": np.float64(EKF_SCAN_SIGMA),
        "control_noise": np.asarray(EKF_CONTROL_NOISE, dtype=float),
    }
