"""A simulated run and the simulator that produces it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from tqdm.auto import tqdm

from robolab.geometry import compose, relative
from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays_reference as cast_rays  # byte-identical data everywhere
from robolab.sim.laser import LaserModel, scan_noise
from robolab.sim.motion import Controller, follow_route
from robolab.sim.odometry import OdometryNoise, odometry_from_truth
from robolab.validation import as_array, check_positive, check_rng

#: ROS time (s since the epoch) of the first message in the bundled bags: 2024-01-01 00:00:00 UTC.
START_TIME = 1_704_067_200.0


@dataclass(frozen=True, eq=False)
class SimRun:
    """One simulated run: arrays only, stamps in seconds since the start.

    Attributes
    ----------
    t : ndarray (K,)
        Stamps of the odometry and ground-truth samples (``odom_rate``).
    true_poses : ndarray (K, 3)
        Ground truth ``map -> base_link``.
    odom_poses : ndarray (K, 3)
        Wheel odometry ``odom -> base_link``; starts at ``(0, 0, 0)``, so
        ``map -> odom`` is the first ground-truth pose plus the drift.
    odom_twist : ndarray (K, 2)
        Velocities ``(v, w)`` reported by the odometry (its motion over the
        previous step divided by the step; 0 at the first sample).
    true_twist : ndarray (K, 2)
        True ``(v, w)`` over the previous step.
    scan_t : ndarray (T,)
        Scan stamps (``scan_rate``); a subset of ``t``.
    scan_poses : ndarray (T, 3)
        Ground-truth base pose at each scan.
    ranges : ndarray (T, B) float32
        Noisy laser ranges, metres (see :class:`LaserModel` for inf / range_max).
    true_ranges : ndarray (T, B)
        Noise-free ray-cast ranges from the laser pose (``range_max``: nothing in range).
    beam_kind : ndarray (T, B) int8
        Cause of each reading: 0 hit, 1 short, 2 max-range failure, 3 random.
    angles : ndarray (B,)
        Beam angles in the laser frame.
    laser_offset : ndarray (3,)
        ``base_link -> base_laser_link``.
    laser, odometry : LaserModel, OdometryNoise
        The parameters used.
    odom_rate, scan_rate : float
        Hz.
    start_time : float
        ROS time of ``t = 0`` in a bag.
    """

    t: np.ndarray
    true_poses: np.ndarray
    odom_poses: np.ndarray
    odom_twist: np.ndarray
    true_twist: np.ndarray
    scan_t: np.ndarray
    scan_poses: np.ndarray
    ranges: np.ndarray
    true_ranges: np.ndarray
    beam_kind: np.ndarray
    angles: np.ndarray
    laser_offset: np.ndarray
    laser: LaserModel = field(default_factory=LaserModel)
    odometry: OdometryNoise = field(default_factory=OdometryNoise)
    odom_rate: float = 20.0
    scan_rate: float = 10.0
    start_time: float = START_TIME

    @property
    def duration(self) -> float:
        """Seconds from the first to the last sample."""
        return float(self.t[-1] - self.t[0])

    @property
    def laser_poses(self) -> np.ndarray:
        """Ground-truth laser poses ``map -> base_laser_link`` at the scans, ``(T, 3)``."""
        return compose(self.scan_poses, self.laser_offset)

    def arrays(self) -> dict[str, np.ndarray]:
        """All arrays by name (for saving and comparing runs)."""
        return {
            k: np.asarray(getattr(self, k))
            for k in (
                "t",
                "true_poses",
                "odom_poses",
                "odom_twist",
                "true_twist",
                "scan_t",
                "scan_poses",
                "ranges",
                "true_ranges",
                "beam_kind",
                "angles",
                "laser_offset",
            )
        }


def clearance_field(grid: OccupancyGrid) -> np.ndarray:
    """Distance in metres from each cell centre to the nearest non-free cell, ``(H, W)``.

    Unknown cells count as obstacles, so the clearance is 0 outside known free space.
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    return ndimage.distance_transform_edt(grid.free) * grid.resolution


def _check_clearance(grid: OccupancyGrid, t, poses, radius: float) -> None:
    clear = clearance_field(grid)
    rc = grid.world_to_cell(poses[:, :2])
    inside = grid.contains_cell(rc)
    d = np.zeros(len(poses))
    d[inside] = clear[rc[inside, 0], rc[inside, 1]]
    bad = np.nonzero(d < radius)[0]
    if bad.size:
        k = bad[0]
        raise ValueError(
            f"route collides: at t = {t[k]:.2f} s the robot at "
            f"({poses[k, 0]:.2f}, {poses[k, 1]:.2f}) is {d[k]:.2f} m from an obstacle "
            f"(robot radius {radius} m)"
        )


def simulate(
    grid: OccupancyGrid,
    route,
    *,
    duration: float,
    rng: np.random.Generator,
    start_pose=None,
    laser: LaserModel = LaserModel(),  # noqa: B008 (frozen dataclass)
    odometry: OdometryNoise = OdometryNoise(),  # noqa: B008 (frozen dataclass)
    controller: Controller = Controller(),  # noqa: B008 (frozen dataclass)
    step_rate: float = 100.0,
    odom_rate: float = 20.0,
    scan_rate: float = 10.0,
    robot_radius: float = 0.2,
    start_time: float = START_TIME,
    progress: bool = False,
) -> SimRun:
    """Drive a differential-drive robot along ``route`` and record truth, odometry and scans.

    Parameters
    ----------
    grid : OccupancyGrid
        The world; cells ``>= grid.occupied_threshold`` reflect the laser.
    route : array_like (W, 2)
        Waypoints in the map frame, metres.
    duration : float
        Seconds to simulate. When the route ends earlier the robot stands still.
    rng : numpy.random.Generator
        All randomness; two streams are spawned (odometry, laser).
    start_pose : array_like (3,), optional
        Initial ground-truth pose; default: the first waypoint, facing the second.
    laser, odometry, controller : LaserModel, OdometryNoise, Controller
        Sensor, drift and controller parameters.
    step_rate, odom_rate, scan_rate : float
        Integration, odometry and scan rates, Hz; the first must be an integer
        multiple of the other two.
    robot_radius : float
        The robot must keep this clearance from every non-free cell.
    start_time : float
        ROS time of ``t = 0`` (used by :func:`write_bag`).
    progress : bool
        Show a tqdm bar while ray casting.

    Returns
    -------
    SimRun

    Raises
    ------
    ValueError
        Bad parameters, or a route that brings the robot closer than
        ``robot_radius`` to an obstacle (the message names time and place).
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    check_rng(rng)
    route = as_array("route", route, ndim=2, finite=True)
    if route.shape[1] != 2 or len(route) < 1:
        raise ValueError(f"route must have shape (W, 2), got {route.shape}")
    if start_pose is None:
        if len(route) < 2:
            raise ValueError("route needs >= 2 waypoints when start_pose is not given")
        d = route[1] - route[0]
        start_pose = (route[0, 0], route[0, 1], np.arctan2(d[1], d[0]))
    step_rate, odom_rate, scan_rate = (
        check_positive(n, v)
        for n, v in (("step_rate", step_rate), ("odom_rate", odom_rate), ("scan_rate", scan_rate))
    )
    odom_every, scan_every = step_rate / odom_rate, step_rate / scan_rate
    for name, ratio in (("odom_rate", odom_every), ("scan_rate", scan_every)):
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"step_rate ({step_rate} Hz) must be an integer multiple of {name}")
    odom_every, scan_every = int(round(odom_every)), int(round(scan_every))
    dt = 1.0 / step_rate
    g_odom, g_scan = rng.spawn(2)

    poses, commands, _ = follow_route(
        route, start_pose, duration=duration, dt=dt, controller=controller
    )
    steps = len(poses)
    t_all = np.arange(steps) / step_rate  # exact multiples of the step, correctly rounded
    _check_clearance(
        grid, t_all, poses, check_positive("robot_radius", robot_radius, allow_zero=True)
    )

    k_odom = np.arange(0, steps, odom_every)
    t = t_all[k_odom]
    true_poses = poses[k_odom]
    odom_poses = odometry_from_truth(true_poses, odometry, g_odom)
    step = 1.0 / odom_rate

    def twist(p):
        rel = relative(p[:-1], p[1:])
        speed = np.hypot(rel[:, 0], rel[:, 1]) * np.where(rel[:, 0] < 0, -1.0, 1.0)
        tw = np.stack([speed, rel[:, 2]], -1) / step
        return np.vstack([np.zeros((1, 2)), tw])

    k_scan = np.arange(0, steps, scan_every)
    scan_poses = poses[k_scan]
    offset = np.asarray(laser.offset, dtype=float)
    laser_poses = compose(scan_poses, offset)
    angles = laser.angles
    cast = cast_rays
    chunk = max(1, 20000 // laser.n_beams)
    true_ranges = np.empty((len(k_scan), laser.n_beams))
    with tqdm(
        total=len(k_scan), desc="ray casting", unit="scan", disable=not progress, leave=False
    ) as bar:
        for s in range(0, len(k_scan), chunk):
            true_ranges[s : s + chunk] = cast(
                grid, laser_poses[s : s + chunk], angles, laser.range_max
            )
            bar.update(min(chunk, len(k_scan) - s))
    ranges, kind = scan_noise(true_ranges, laser, g_scan)
    return SimRun(
        t=t,
        true_poses=true_poses,
        odom_poses=odom_poses,
        odom_twist=twist(odom_poses),
        true_twist=twist(true_poses),
        scan_t=t_all[k_scan],
        scan_poses=scan_poses,
        ranges=ranges,
        true_ranges=true_ranges,
        beam_kind=kind,
        angles=angles,
        laser_offset=offset,
        laser=laser,
        odometry=odometry,
        odom_rate=odom_rate,
        scan_rate=scan_rate,
        start_time=float(start_time),
    )
