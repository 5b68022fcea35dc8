"""Driving a route: the waypoint controller and the motion integration."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array, as_poses, check_positive


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


def _step_pose(x: float, y: float, th: float, v: float, w: float, dt: float, model: str):
    """Advance a unicycle by ``dt``: exact circular arc, or the Euler step of lab 06."""
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
        (the bags), or lab 06's Euler model ``x += v cos(theta) dt``,
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
