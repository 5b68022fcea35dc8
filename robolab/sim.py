"""The simulator behind the bundled data, and ``robolab data``.

A differential-drive robot follows a route of waypoints through an occupancy
grid. The simulator records

- the **ground truth** pose ``map -> base_link``;
- **wheel odometry** ``odom -> base_link`` that drifts like a real robot's:
  every odometry step perturbs the true relative motion ``(rot1, trans, rot2)``
  with the noise of the odometry motion model (Probabilistic Robotics,
  Table 5.6, run "in reverse": the robot moves along the true path and the
  *reported* motion is the noisy one) and a small systematic bias from
  wheel-radius and wheel-base calibration errors, so that a map built from raw
  odometry smears (lab 04);
- **laser scans** ray cast from the laser's true pose ``base_link ->
  base_laser_link`` with the noise of the beam model (Table 6.1): Gaussian hit
  noise, short readings, max-range failures and random readings.

:func:`write_bag` stores a run as a ROS1 bag, :func:`make_data` regenerates
every file in ``data/`` from fixed seeds (see ``data/README.md``).

Time: a run's stamps ``t`` are seconds since the start of the run; the bag
stamps are ``start_time + t`` (ROS time, seconds since the epoch).
"""

from __future__ import annotations

import io
import sys
import zipfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage
from tqdm.auto import tqdm

from robolab.geometry import compose, relative, wrap_angle
from robolab.maps import OccupancyGrid, save_map
from robolab.raycast import cast_rays_reference as cast_rays  # byte-identical data everywhere
from robolab.validation import as_array, as_poses, check_positive, check_rng

__all__ = [
    "LaserModel",
    "OdometryNoise",
    "Controller",
    "SimRun",
    "follow_route",
    "simulate",
    "write_bag",
    "odometry_from_truth",
    "scan_noise",
    "clearance_field",
    "mapping_run",
    "localization_run",
    "ekf_world",
    "make_data",
    "DATASETS",
    "START_TIME",
    "BAG_TOPICS",
    "MAPPING_ROUTE",
    "MAPPING_START",
    "LOCALIZATION_ROUTE",
    "LOCALIZATION_START",
]

#: ROS time (s since the epoch) of the first message in the bundled bags: 2024-01-01 00:00:00 UTC.
START_TIME = 1_704_067_200.0


# ---------------------------------------------------------------------------
# parameters
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class LaserModel:
    """A planar laser scanner and the noise of the beam model (Table 6.1).

    Each reading comes from one of four causes, drawn per beam with
    probabilities ``z_hit, z_short, z_max, z_rand`` (normalized to sum 1):

    - hit: the ray-cast range plus Gaussian noise ``N(0, sigma_hit**2)``,
      clipped to ``[range_min, range_max]``;
    - short: an unexpected obstacle, exponential with rate ``lambda_short``
      truncated to ``[0, z*]`` (``z*`` the true range, or ``range_max`` when
      nothing is in range); a short reading may fall below ``range_min`` and
      must then be discarded, as sensor_msgs/LaserScan says;
    - max: a sensor failure (glass, black surfaces), reported as exactly
      ``range_max``: the point mass ``p_max`` of the beam model;
    - rand: uniform on ``[0, range_max)``.

    A beam whose ray meets no obstacle within ``range_max`` and whose cause is
    a hit reports ``+inf`` (REP-117: "no object detected in range"). So "no
    return" appears in two encodings, ``range_max`` (failures) and ``inf``
    (nothing in range), and readers must handle both explicitly.

    Parameters
    ----------
    n_beams : int
        Number of beams; beam ``i`` points at ``angle_min + i * angle_increment``
        relative to the laser's heading, with ``angle_increment = 2 pi / n_beams``
        when ``fov`` is the full circle.
    angle_min : float
        Angle of the first beam, radians.
    fov : float
        Angular span covered by the beams, radians (``2 pi``: full circle).
    range_min, range_max : float
        Valid range interval, metres.
    sigma_hit, lambda_short : float
        Hit noise standard deviation (m) and short-reading rate (1/m).
    z_hit, z_short, z_max, z_rand : float
        Mixing weights of the four causes.
    offset : (x, y, theta)
        Pose of ``base_laser_link`` in ``base_link``.
    """

    n_beams: int = 360
    angle_min: float = -np.pi
    fov: float = 2.0 * np.pi
    range_min: float = 0.05
    range_max: float = 8.0
    sigma_hit: float = 0.02
    lambda_short: float = 0.5
    z_hit: float = 0.91
    z_short: float = 0.04
    z_max: float = 0.03
    z_rand: float = 0.02
    offset: tuple[float, float, float] = (0.10, 0.0, 0.0)

    def __post_init__(self):
        if int(self.n_beams) != self.n_beams or self.n_beams < 1:
            raise ValueError(f"n_beams must be a positive integer, got {self.n_beams!r}")
        check_positive("range_max", self.range_max)
        check_positive("range_min", self.range_min, allow_zero=True)
        if self.range_min >= self.range_max:
            raise ValueError(f"range_min ({self.range_min}) must be < range_max ({self.range_max})")
        check_positive("fov", self.fov)
        check_positive("sigma_hit", self.sigma_hit, allow_zero=True)
        check_positive("lambda_short", self.lambda_short)
        weights = np.array([self.z_hit, self.z_short, self.z_max, self.z_rand], dtype=float)
        if np.any(weights < 0) or weights.sum() <= 0:
            raise ValueError(
                f"z_hit, z_short, z_max, z_rand must be >= 0 with a positive sum, got {weights}"
            )
        as_array("offset", self.offset, shape=(3,), finite=True)

    @property
    def angle_increment(self) -> float:
        """Angle between neighbouring beams, radians."""
        full = np.isclose(self.fov, 2.0 * np.pi)
        return float(self.fov / (self.n_beams if full or self.n_beams == 1 else self.n_beams - 1))

    @property
    def angles(self) -> np.ndarray:
        """Beam angles relative to the laser's heading, shape ``(n_beams,)``."""
        return self.angle_min + self.angle_increment * np.arange(self.n_beams)

    @property
    def weights(self) -> np.ndarray:
        """``(z_hit, z_short, z_max, z_rand)`` normalized to sum 1."""
        w = np.array([self.z_hit, self.z_short, self.z_max, self.z_rand], dtype=float)
        return w / w.sum()


@dataclass(frozen=True)
class OdometryNoise:
    """Drift of wheel odometry: random motion-model noise plus calibration bias.

    Random part (Table 5.6 of Probabilistic Robotics, applied to the reported
    motion of each odometry step, ``1 / odom_rate`` seconds), with variances

    - ``rot1``: ``alpha1 * rot1**2 + alpha2 * trans**2``
    - ``trans``: ``alpha3 * trans**2 + alpha4 * (rot1**2 + rot2**2)``
    - ``rot2``: ``alpha1 * rot2**2 + alpha2 * trans**2``

    Systematic part: the odometry integrates wheel travel with wrong wheel
    radii and a wrong wheel base. With true wheel travel ``d_l, d_r`` the
    encoders report ``scale_left * d_l`` and ``scale_right * d_r``, and the
    heading change is computed with the wheel base ``wheel_base * wheel_base_scale``.
    ``scale_right != scale_left`` bends straight lines (a slow heading drift);
    ``wheel_base_scale != 1`` over- or under-states every turn.

    Parameters
    ----------
    alpha1, alpha2, alpha3, alpha4 : float
        Motion-model noise (rad^2/rad^2, rad^2/m^2, m^2/m^2, m^2/rad^2).
    wheel_base : float
        Distance between the wheels, metres.
    scale_left, scale_right : float
        Reported / true travel of each wheel.
    wheel_base_scale : float
        Wheel base assumed by the odometry / true wheel base.
    """

    alpha1: float = 0.02
    alpha2: float = 0.01
    alpha3: float = 0.02
    alpha4: float = 0.005
    wheel_base: float = 0.35
    scale_left: float = 1.0
    scale_right: float = 1.002
    wheel_base_scale: float = 0.99

    def __post_init__(self):
        for name in ("alpha1", "alpha2", "alpha3", "alpha4"):
            check_positive(name, getattr(self, name), allow_zero=True)
        for name in ("wheel_base", "scale_left", "scale_right", "wheel_base_scale"):
            check_positive(name, getattr(self, name))


@dataclass(frozen=True)
class Controller:
    """Turn-then-drive waypoint follower for a differential-drive robot.

    The robot turns towards the next waypoint, rotating in place while the
    heading error exceeds ``turn_threshold``, and drives forward otherwise with
    ``v = min(v_max, k_v * distance + v_min) * cos(heading error)`` and
    ``w = k_w * heading error``, both limited by ``w_max`` and the
    accelerations ``a_max``, ``alpha_max``. A waypoint counts as reached within
    ``tolerance``. The robot never drives backwards.
    """

    v_max: float = 0.6
    v_min: float = 0.05
    w_max: float = 1.5
    k_v: float = 1.5
    k_w: float = 2.5
    turn_threshold: float = 0.35
    tolerance: float = 0.08
    a_max: float = 1.0
    alpha_max: float = 4.0

    def __post_init__(self):
        for name in (
            "v_max",
            "w_max",
            "k_v",
            "k_w",
            "turn_threshold",
            "tolerance",
            "a_max",
            "alpha_max",
        ):
            check_positive(name, getattr(self, name))
        check_positive("v_min", self.v_min, allow_zero=True)


# ---------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------
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


# ---------------------------------------------------------------------------
# motion
# ---------------------------------------------------------------------------
def _step_pose(x: float, y: float, th: float, v: float, w: float, dt: float, model: str):
    """Advance a unicycle by ``dt``: exact circular arc, or the Euler step of seed 000."""
    if model == "euler":
        return x + v * np.cos(th) * dt, y + v * np.sin(th) * dt, wrap_angle(th + w * dt)
    if abs(w) < 1e-9:
        return x + v * np.cos(th) * dt, y + v * np.sin(th) * dt, th
    r = v / w
    th2 = th + w * dt
    return x + r * (np.sin(th2) - np.sin(th)), y - r * (np.cos(th2) - np.cos(th)), wrap_angle(th2)


def follow_route(
    route,
    start_pose,
    *,
    duration: float,
    dt: float,
    controller: Controller = Controller(),
    model: str = "arc",
    control_noise: tuple[float, float] = (0.0, 0.0),
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Drive a unicycle along waypoints with :class:`Controller`.

    Parameters
    ----------
    route : array_like (W, 2)
        Waypoints, visited in order. After the last one the robot stops.
    start_pose : array_like (3,)
        Initial pose.
    duration : float
        Seconds to simulate; ``round(duration / dt)`` steps are taken.
    dt : float
        Step, seconds.
    controller : Controller
        Gains and limits.
    model : {"arc", "euler"}
        Motion integration: the exact circular arc of a constant ``(v, w)``
        (the bags), or seed 000's Euler model ``x += v cos(theta) dt``,
        ``theta += w dt`` (the EKF world).
    control_noise : (sigma_v, sigma_w)
        Standard deviations of Gaussian noise added to the *executed*
        velocities (the returned commands stay the noise-free ones).
    rng : numpy.random.Generator, optional
        Needed when ``control_noise`` is non-zero.

    Returns
    -------
    poses : ndarray (S + 1, 3)
        Poses at ``k * dt``, ``poses[0] == start_pose``.
    commands : ndarray (S, 2)
        Commanded ``(v, w)`` applied during step ``k``.
    reached : ndarray (W,) bool
        Which waypoints were reached.
    """
    route = as_array("route", route, ndim=2, finite=True)
    if route.shape[1] != 2 or len(route) < 1:
        raise ValueError(f"route must have shape (W, 2) with W >= 1, got {route.shape}")
    start = as_poses("start_pose", start_pose)
    if len(start) != 1:
        raise ValueError("start_pose must be a single pose (3,)")
    duration = check_positive("duration", duration)
    dt = check_positive("dt", dt)
    if model not in ("arc", "euler"):
        raise ValueError(f"model must be 'arc' or 'euler', got {model!r}")
    cn = as_array("control_noise", control_noise, shape=(2,), finite=True, nonnegative=True)
    sv, sw = float(cn[0]), float(cn[1])
    steps = int(round(duration / dt))
    noise = np.zeros((steps, 2))
    if sv > 0 or sw > 0:
        if rng is None:
            raise ValueError("rng is required when control_noise is non-zero")
        noise = rng.standard_normal((steps, 2)) * (sv, sw)

    c = controller
    poses = np.empty((steps + 1, 3))
    commands = np.zeros((steps, 2))
    x, y, th = (float(v) for v in start[0])
    poses[0] = x, y, th
    v = w = 0.0
    i = 0
    n_wp = len(route)
    for k in range(steps):
        v_cmd = w_cmd = 0.0
        while i < n_wp and np.hypot(route[i, 0] - x, route[i, 1] - y) < c.tolerance:
            i += 1
        if i < n_wp:
            dx, dy = route[i, 0] - x, route[i, 1] - y
            dist = np.hypot(dx, dy)
            err = wrap_angle(np.arctan2(dy, dx) - th)
            w_cmd = float(np.clip(c.k_w * err, -c.w_max, c.w_max))
            if abs(err) < c.turn_threshold:
                v_cmd = min(c.v_max, c.k_v * dist + c.v_min) * np.cos(err)
        # acceleration limits
        v += float(np.clip(v_cmd - v, -c.a_max * dt, c.a_max * dt))
        w += float(np.clip(w_cmd - w, -c.alpha_max * dt, c.alpha_max * dt))
        commands[k] = v, w
        x, y, th = _step_pose(x, y, th, max(v + noise[k, 0], 0.0), w + noise[k, 1], dt, model)
        poses[k + 1] = x, y, th
    reached = np.arange(n_wp) < i
    return poses, commands, reached


def odometry_from_truth(true_poses, noise: OdometryNoise, rng: np.random.Generator) -> np.ndarray:
    """Wheel odometry that drifts away from a true trajectory.

    The true relative motion between consecutive samples, decomposed as
    ``(rot1, trans, rot2)`` (Table 5.5), is distorted by the wheel calibration
    errors of ``noise`` and then perturbed with the motion-model noise of
    Table 5.6; the distorted steps are chained from ``(0, 0, 0)``.

    Parameters
    ----------
    true_poses : array_like (K, 3)
        Ground-truth poses at the odometry rate.
    noise : OdometryNoise
        Noise and bias parameters (per step).
    rng : numpy.random.Generator
        Source of the noise; ``3 (K - 1)`` standard normals are drawn in one
        call, so a shorter run reproduces the start of a longer one.

    Returns
    -------
    ndarray (K, 3)
        Odometry poses ``odom -> base_link``; the first is ``(0, 0, 0)``.
    """
    p = as_poses("true_poses", true_poses)
    if not isinstance(noise, OdometryNoise):
        raise TypeError(f"noise must be an OdometryNoise, got {type(noise).__name__}")
    rel = relative(p[:-1], p[1:])
    trans = np.hypot(rel[:, 0], rel[:, 1])
    rot1 = np.where(trans > 1e-9, np.arctan2(rel[:, 1], rel[:, 0]), 0.0)
    dth = rel[:, 2]
    rot2 = wrap_angle(dth - rot1)
    # systematic: wheel travel measured with wrong radii, heading with a wrong wheel base
    half_b = 0.5 * noise.wheel_base
    d_r = noise.scale_right * (trans + dth * half_b)
    d_l = noise.scale_left * (trans - dth * half_b)
    trans_b = 0.5 * (d_r + d_l)
    dth_b = (d_r - d_l) / (noise.wheel_base * noise.wheel_base_scale)
    rot1_b = rot1 + 0.5 * (dth_b - dth)
    rot2_b = rot2 + 0.5 * (dth_b - dth)
    # random: Table 5.6 variances
    e = rng.standard_normal((len(rel), 3))
    a1, a2, a3, a4 = noise.alpha1, noise.alpha2, noise.alpha3, noise.alpha4
    r1 = rot1_b + e[:, 0] * np.sqrt(a1 * rot1_b**2 + a2 * trans_b**2)
    tr = trans_b + e[:, 1] * np.sqrt(a3 * trans_b**2 + a4 * (rot1_b**2 + rot2_b**2))
    r2 = rot2_b + e[:, 2] * np.sqrt(a1 * rot2_b**2 + a2 * trans_b**2)
    # chain the steps from the origin (vectorized: headings are a cumulative sum)
    heading = np.concatenate([[0.0], np.cumsum(r1 + r2)])
    out = np.zeros((len(p), 3))
    out[1:, 0] = np.cumsum(tr * np.cos(heading[:-1] + r1))
    out[1:, 1] = np.cumsum(tr * np.sin(heading[:-1] + r1))
    out[:, 2] = wrap_angle(heading)
    return out


# ---------------------------------------------------------------------------
# sensing
# ---------------------------------------------------------------------------
def scan_noise(
    true_ranges, laser: LaserModel, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Apply the beam-model noise of :class:`LaserModel` to ray-cast ranges.

    Parameters
    ----------
    true_ranges : array_like (T, B)
        Noise-free ranges; values ``>= laser.range_max`` mean nothing in range.
    laser : LaserModel
        The noise parameters.
    rng : numpy.random.Generator
        Four independent streams are spawned from it (cause, hit noise, short
        readings, random readings), each drawn as one ``(T, B)`` block, so a
        shorter run reproduces the start of a longer one.

    Returns
    -------
    ranges : ndarray (T, B) float32
        Noisy readings: finite values, ``range_max`` (failures) or ``+inf``
        (nothing in range).
    kind : ndarray (T, B) int8
        0 hit, 1 short, 2 max-range failure, 3 random.
    """
    z = as_array("true_ranges", true_ranges, ndim=2, nonnegative=True)
    r_max = laser.range_max
    g_kind, g_hit, g_short, g_rand = rng.spawn(4)
    u = g_kind.random(z.shape)
    kind = np.searchsorted(np.cumsum(laser.weights)[:-1], u, side="right").astype(np.int8)
    nothing = z >= r_max
    zc = np.minimum(z, r_max)
    hit = np.clip(zc + laser.sigma_hit * g_hit.standard_normal(z.shape), laser.range_min, r_max)
    hit[nothing] = np.inf
    # exponential truncated to [0, z*] by inverting its CDF
    lam = laser.lambda_short
    short = -np.log1p(-g_short.random(z.shape) * -np.expm1(-lam * zc)) / lam
    rand = g_rand.random(z.shape) * r_max
    out = np.choose(kind, [hit, short, np.full(z.shape, r_max), rand])
    return out.astype(np.float32), kind


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
    laser: LaserModel = LaserModel(),
    odometry: OdometryNoise = OdometryNoise(),
    controller: Controller = Controller(),
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


# ---------------------------------------------------------------------------
# bags
# ---------------------------------------------------------------------------
#: Topics of the simulated bags: name -> (message type, frame_id, child frame or None).
BAG_TOPICS = {
    "/base_scan": ("sensor_msgs/msg/LaserScan", "base_laser_link", None),
    "/odom": ("nav_msgs/msg/Odometry", "odom", "base_link"),
    "/ground_truth": ("nav_msgs/msg/Odometry", "map", "base_link"),
    "/tf": ("tf2_msgs/msg/TFMessage", None, None),
}


def write_bag(
    run: SimRun,
    path,
    *,
    truth_rate: float | None = None,
    compression: str | None = "lz4",
    progress: bool = False,
) -> Path:
    """Write a run as a ROS1 bag (v2.0).

    Topics (stamps ``run.start_time + t``; messages written in time order):

    - ``/odom`` (nav_msgs/Odometry, ``odom -> base_link``, ``odom_rate``):
      odometry pose and its twist ``(v, w)``;
    - ``/ground_truth`` (nav_msgs/Odometry, ``map -> base_link``, ``truth_rate``,
      by default the scan rate, so every scan has its true pose at its stamp);
    - ``/tf`` (tf2_msgs/TFMessage): ``odom -> base_link`` at ``odom_rate``, and
      ``base_link -> base_laser_link`` at ``scan_rate`` with each scan's stamp,
      as ROS1's ``static_transform_publisher`` did (so a tool that replays only
      ``/tf`` and the scans, like seed 000's processBag, has the laser frame);
      there is no ``/tf_static`` and no ``map -> odom`` (localization's job);
    - ``/base_scan`` (sensor_msgs/LaserScan, frame ``base_laser_link``,
      ``scan_rate``): all beams are taken at the stamp (``time_increment = 0``,
      ``scan_time = 1 / scan_rate``), no intensities.

    Parameters
    ----------
    run : SimRun
    path : str or Path
        Output ``.bag`` file; an existing file is replaced once the new one is
        complete.
    truth_rate : float, optional
        Rate of ``/ground_truth`` in Hz; must divide ``run.odom_rate``.
        Default ``run.scan_rate``.
    compression : {"lz4", "bz2", None}
        Chunk compression (default lz4: about 3x smaller, fast to read).
    progress : bool
        Show a tqdm bar.

    Returns
    -------
    Path
    """
    from robolab.bag import BagWriter

    if not isinstance(run, SimRun):
        raise TypeError(f"run must be a SimRun, got {type(run).__name__}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    truth_rate = run.scan_rate if truth_rate is None else check_positive("truth_rate", truth_rate)
    every = run.odom_rate / truth_rate
    if abs(every - round(every)) > 1e-9 or round(every) < 1:
        raise ValueError(
            f"truth_rate ({truth_rate} Hz) must divide the odometry rate ({run.odom_rate} Hz)"
        )
    every = int(round(every))
    t0 = run.start_time
    lz = run.laser
    # events: (time, order, kind, index) -> written in time order, odometry before scans at a tie
    ev_t = np.concatenate([run.t, run.scan_t])
    ev_kind = np.concatenate([np.zeros(len(run.t), int), np.ones(len(run.scan_t), int)])
    ev_idx = np.concatenate([np.arange(len(run.t)), np.arange(len(run.scan_t))])
    order = np.lexsort((ev_kind, ev_t))
    with (
        BagWriter(path, compression=compression) as bag,
        tqdm(
            total=len(order),
            desc=f"writing {path.name}",
            unit="msg",
            disable=not progress,
            leave=False,
        ) as bar,
    ):
        for e in order:
            k = int(ev_idx[e])
            if ev_kind[e] == 0:
                stamp = t0 + float(run.t[k])
                bag.write_tf(stamp, [("odom", "base_link", run.odom_poses[k])])
                bag.write_odometry(
                    "/odom",
                    stamp,
                    run.odom_poses[k],
                    frame_id="odom",
                    child_frame_id="base_link",
                    twist=tuple(run.odom_twist[k]),
                )
                if k % every == 0:
                    bag.write_odometry(
                        "/ground_truth",
                        stamp,
                        run.true_poses[k],
                        frame_id="map",
                        child_frame_id="base_link",
                        twist=tuple(run.true_twist[k]),
                    )
            else:
                stamp = t0 + float(run.scan_t[k])
                bag.write_tf(stamp, [("base_link", "base_laser_link", run.laser_offset)])
                bag.write_scan(
                    "/base_scan",
                    stamp,
                    run.ranges[k],
                    angle_min=float(run.angles[0]),
                    angle_increment=lz.angle_increment,
                    range_min=lz.range_min,
                    range_max=lz.range_max,
                    frame_id="base_laser_link",
                    scan_time=1.0 / run.scan_rate,
                    time_increment=0.0,
                )
            bar.update(1)
    return path


# ---------------------------------------------------------------------------
# the bundled runs
# ---------------------------------------------------------------------------
#: Seeds of the bundled data sets.
SEEDS = {"mapping": 4, "localization": 5, "ekf_world": 6}
#: Length of the bundled runs, seconds.
MAPPING_DURATION = 80.0
LOCALIZATION_DURATION = 85.0

#: Mapping route: corridor -> open-plan room (around a pillar) -> corridor ->
#: north office 2 (around its table) -> back into the corridor.
MAPPING_ROUTE = np.array(
    [
        [1.0, 6.0],
        [3.75, 6.0],
        [3.75, 3.8],
        [6.6, 3.8],
        [6.6, 1.3],
        [4.0, 1.3],
        [4.0, 6.0],
        [11.5, 6.0],
        [11.5, 8.0],
        [14.3, 8.0],
        [14.3, 10.2],
        [11.5, 10.2],
        [11.5, 6.0],
    ]
)

#: Localization route: starts inside north office 1 (four identical offices:
#: global localization is ambiguous until the robot sees the corridor), leaves
#: it, drives west along the corridor, loops through the open-plan room and
#: drives east along the corridor.
LOCALIZATION_ROUTE = np.array(
    [
        [7.2, 9.8],
        [9.2, 9.8],
        [9.2, 8.0],
        [6.5, 8.0],
        [6.5, 6.0],
        [3.75, 6.0],
        [3.75, 3.8],
        [7.0, 3.8],
        [7.0, 1.5],
        [4.0, 1.5],
        [4.0, 6.0],
        [18.5, 6.0],
    ]
)
# The start poses sit a little off the 5 cm cell boundaries (1.0, 6.0 and 7.2,
# 9.8 lie exactly on them), which keeps every ray of the first scan off a grid line.
#: Initial ground-truth pose of the mapping run.
MAPPING_START = (1.03, 6.02, 0.0)
#: Initial ground-truth pose of the localization run, inside the second north office.
LOCALIZATION_START = (7.23, 9.82, 0.0)


def _office() -> OccupancyGrid:
    from robolab.floorplan import office_floorplan

    return office_floorplan()


def mapping_run(duration: float = MAPPING_DURATION, *, progress: bool = False) -> SimRun:
    """The run behind ``data/mapping.bag`` (seed ``SEEDS["mapping"]``).

    A shorter ``duration`` reproduces the start of the full run exactly.
    """
    return simulate(
        _office(),
        MAPPING_ROUTE,
        start_pose=MAPPING_START,
        duration=duration,
        rng=np.random.default_rng(SEEDS["mapping"]),
        progress=progress,
    )


def localization_run(duration: float = LOCALIZATION_DURATION, *, progress: bool = False) -> SimRun:
    """The run behind ``data/localization.bag`` (seed ``SEEDS["localization"]``).

    A shorter ``duration`` reproduces the start of the full run exactly.
    """
    return simulate(
        _office(),
        LOCALIZATION_ROUTE,
        duration=duration,
        start_pose=LOCALIZATION_START,
        rng=np.random.default_rng(SEEDS["localization"]),
        progress=progress,
    )


# -- the EKF world of seed 000 ------------------------------------------------------
EKF_SIZE = 40
EKF_ZMAX = 20.0
EKF_DT = 0.1
EKF_N_BEAMS = 36
EKF_ROUTE = np.array([[30.0, 10.0], [30.0, 30.0], [10.0, 30.0], [10.0, 10.0], [30.0, 10.0]])
EKF_START = (10.0, 10.0, 0.0)
EKF_DURATION = 50.0
EKF_CONTROL_NOISE = (0.05, 0.02)  # std of executed speed (units/s) and rotation speed (rad/s)
EKF_SCAN_SIGMA = 0.2  # units
EKF_PROCESS_NOISE = np.diag([0.0001, 0.0001, 0.08])  # seed 000's pNoise
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
    """The simulated world of lab 06 (seed 000, section 4) as a dict of arrays.

    A 40 x 40 cell world (1 unit per cell, border walls and block obstacles)
    and a 50 s run of seed 000's unicycle transition model
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
        (seed 000 indexes ``map(x, y)``: use ``world.T``); ``resolution``;
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


def _save_npz(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    """Like ``numpy.savez_compressed`` but byte-for-byte reproducible (fixed zip timestamps)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, arr in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asarray(arr), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue())
    return path


# -- make_data -----------------------------------------------------------------
def _make_office(out: Path, progress: bool) -> list[Path]:
    y = save_map(_office(), out / "office.yaml")
    return [y, y.with_suffix(".pgm")]


def _make_mapping(out: Path, progress: bool) -> list[Path]:
    return [write_bag(mapping_run(progress=progress), out / "mapping.bag", progress=progress)]


def _make_localization(out: Path, progress: bool) -> list[Path]:
    return [
        write_bag(localization_run(progress=progress), out / "localization.bag", progress=progress)
    ]


def _make_ekf_world(out: Path, progress: bool) -> list[Path]:
    return [_save_npz(out / "ekf_world.npz", ekf_world())]


def _make_maze(out: Path, progress: bool) -> list[Path]:
    from robolab.maze import write_maze

    y = Path(write_maze(out))
    return [y, out / "maze.png"]


def _make_fastslam(out: Path, progress: bool) -> list[Path]:
    from robolab.fiducials import write_run

    return [Path(write_run(out / "fastslam.npz", seed=0))]


#: Data set name -> the function that writes it into a folder.
DATASETS: dict[str, Callable[[Path, bool], list[Path]]] = {
    "office": _make_office,
    "mapping": _make_mapping,
    "localization": _make_localization,
    "ekf_world": _make_ekf_world,
    "maze": _make_maze,
    "fastslam": _make_fastslam,
}


def make_data(
    out_dir=None, only: Iterable[str] | None = None, *, progress: bool = True
) -> list[Path]:
    """Regenerate the bundled data deterministically (``robolab data``).

    Parameters
    ----------
    out_dir : str or Path, optional
        Output folder; default :data:`robolab.DATA_DIR` (the repository's ``data/``).
    only : iterable of str, optional
        Names of the data sets to make (see :data:`DATASETS`); default all.
        ``office``: office.yaml + office.pgm; ``mapping``: mapping.bag;
        ``localization``: localization.bag; ``ekf_world``: ekf_world.npz;
        ``maze``: maze.png + maze.yaml; ``fastslam``: fastslam.npz.
    progress : bool
        Show tqdm progress bars.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    ValueError
        An unknown name in ``only`` (the message lists the valid ones).
    """
    if out_dir is None:
        from robolab import DATA_DIR

        out_dir = DATA_DIR
    out = Path(out_dir)
    if isinstance(only, str):
        only = [only]
    if only is not None:
        only = list(only)
        if not all(isinstance(n, str) for n in only):
            raise TypeError(f"only must be data set names (str), got {only!r}")
    names = list(DATASETS) if not only else list(dict.fromkeys(only))
    unknown = [n for n in names if n not in DATASETS]
    if unknown:
        raise ValueError(
            f"unknown data set(s) {', '.join(map(repr, unknown))}; "
            f"valid names: {', '.join(DATASETS)}"
        )
    written: list[Path] = []
    out.mkdir(parents=True, exist_ok=True)
    with tqdm(names, desc="robolab data", unit="set", disable=not progress, file=sys.stderr) as bar:
        for name in bar:
            bar.set_postfix_str(name)
            written += DATASETS[name](out, progress)
    return written
