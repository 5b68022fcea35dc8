"""The fiducial robot of the FastSLAM lab (lab 07; ``Robot.m`` in MATLAB versions of the lab).

A unicycle robot drives a closed loop around a handful of fiducials (visual
markers with known identities) and reports, at every step, the command it was
given and the range, bearing and identity of every fiducial it can see.

Motion model (the one lab 07 ``fastslam`` uses in ``predict_poses``)::

    x'     = x + v dt cos(theta)  + w_x
    y'     = y + v dt sin(theta)  + w_y
    theta' = theta + omega dt     + w_theta,      w ~ N(0, Q),

with the command ``u = [v, omega]`` (m/s, rad/s), ``dt`` in seconds, ``Q`` a
3 x 3 covariance of additive pose noise per step, and ``theta'`` wrapped to
``[-pi, pi)`` with :func:`robolab.geometry.wrap_angle`.

Measurement model: for every fiducial ``(m_x, m_y)`` with ``min_range <= r <= max_range``
and ``|phi| <= fov / 2`` (decided on the true, noise-free range and bearing)::

    r   = sqrt((m_x - x)^2 + (m_y - y)^2)              + v_r
    phi = wrap(atan2(m_y - y, m_x - x) - theta)        + v_phi,   v ~ N(0, Qt),

and ``phi`` is wrapped again after the noise is added. Rows are
``[range, bearing, id]`` with ``id`` the fiducial's index (0-based, as float).

The default world has five fiducials around the start pose
``x0 = [-2.5, -2, 0.25]`` (see :data:`FIDUCIALS`)::

    id   x (m)   y (m)
     0   -3.5     1.0    inside the loop, seen about half of the time
     1    1.0     1.5    east of the loop
     2   -3.0     5.5    north
     3   -8.0     2.0    west
     4   -2.0    -3.5    south, near the start

and the route (:meth:`FiducialRobot.input`) is a rounded triangle of about
7 m x 6.5 m that closes every 20 s (200 steps at ``dt = 0.1``): ``v = 1 m/s``,
``omega(t) = w0 (1 + cos(3 w0 t))`` with ``w0 = 2 pi / 20 s``. The default run
of 600 steps goes three times around, so every fiducial is revisited (loop
closure). More fiducials (``n_fiducials > 5``, e.g. 15 for the benchmark) are
added on a fixed golden-angle spiral around the loop's centre, independent of
the random seed.

The whole run (motion noise and measurement noise) is drawn at construction
from ``numpy.random.default_rng(seed)``, so a robot is a deterministic replay:
calling :meth:`FiducialRobot.measurement` twice in one step gives the same
rows. Ground truth is kept in :attr:`FiducialRobot.true_poses` and
:attr:`FiducialRobot.fiducials` for grading and plots.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_covariance, check_positive

__all__ = [
    "FIDUCIALS",
    "X0",
    "DT",
    "Q_DEFAULT",
    "QT_DEFAULT",
    "FOV_DEFAULT",
    "MAX_RANGE_DEFAULT",
    "MIN_RANGE_DEFAULT",
    "N_STEPS_DEFAULT",
    "FiducialRobot",
    "FiducialRun",
    "fiducial_layout",
    "route_command",
    "unicycle",
    "as_robot",
    "write_run",
    "load_run",
    "sqrt_psd",
]

#: The five fiducials of the lab, metres, one row per id.
FIDUCIALS = np.array([(-3.5, 1.0), (1.0, 1.5), (-3.0, 5.5), (-8.0, 2.0), (-2.0, -3.5)])
#: Start pose of the lab's robot: x0 = [-2.5, -2, 0.25] (m, m, rad).
X0 = np.array([-2.5, -2.0, 0.25])
#: Time step, s.
DT = 0.1
#: Additive pose noise per step: 2 cm in x and y, 0.5 degree in heading.
Q_DEFAULT = np.diag([0.02**2, 0.02**2, np.deg2rad(0.5) ** 2])
#: Measurement noise: 10 cm in range, 2 degrees in bearing.
QT_DEFAULT = np.diag([0.1**2, np.deg2rad(2.0) ** 2])
#: Field of view, rad (total opening, centred on the heading): the front half-plane.
FOV_DEFAULT = np.pi
#: Largest range at which a fiducial is detected, m.
MAX_RANGE_DEFAULT = 5.0
#: Smallest range at which a fiducial is detected, m (a marker under the camera is not
#: seen; 5 range standard deviations, so a measured range is practically never negative).
MIN_RANGE_DEFAULT = 0.5
#: Default length of a run: three loops of 20 s.
N_STEPS_DEFAULT = 600

_LOOP_PERIOD = 20.0  # s, one time around the route
_SPEED = 1.0  # m/s
_LOOP_CENTRE = np.array([-3.4, 1.4])  # mean position of the noise-free route, m


def fiducial_layout(n_fiducials: int = 5) -> np.ndarray:
    """Positions of ``n_fiducials`` fiducials, shape ``(n_fiducials, 2)``, metres.

    The first five are :data:`FIDUCIALS`; any further ones lie on a golden-angle
    spiral around the loop's centre (radii 2 m to 7 m), so that a larger world
    (15 fiducials for the benchmark) has fiducials inside and outside the route.
    """
    n = int(n_fiducials)
    if n != n_fiducials or n < 1:
        raise ValueError(f"n_fiducials must be a positive integer, got {n_fiducials!r}")
    if n <= len(FIDUCIALS):
        return FIDUCIALS[:n].copy()
    extra = n - len(FIDUCIALS)
    i = np.arange(extra)
    golden = np.pi * (3.0 - np.sqrt(5.0))
    radius = 2.0 + 5.0 * (i + 0.5) / extra
    angle = 2.53 + golden * i
    pts = _LOOP_CENTRE + radius[:, None] * np.stack([np.cos(angle), np.sin(angle)], -1)
    return np.vstack([FIDUCIALS, pts])


def route_command(t) -> np.ndarray:
    """The route's command ``[v, omega]`` at time(s) ``t`` (s); shape ``(2,)`` or ``(T, 2)``.

    ``v = 1 m/s`` and ``omega = w0 (1 + cos(3 w0 t))`` with ``w0 = 2 pi / 20 s``: the
    heading turns by exactly ``2 pi`` every 20 s and the noise-free path is a
    closed rounded triangle.
    """
    t = np.asarray(t, dtype=float)
    w0 = 2.0 * np.pi / _LOOP_PERIOD
    omega = w0 * (1.0 + np.cos(3.0 * w0 * t))
    return np.stack([np.full_like(omega, _SPEED), omega], -1)


def unicycle(pose, command, dt: float = DT) -> np.ndarray:
    """Noise-free unicycle step, broadcast over leading dimensions.

    ``x' = x + v dt cos(theta)``, ``y' = y + v dt sin(theta)``,
    ``theta' = wrap(theta + omega dt)``.

    Parameters
    ----------
    pose : array_like, shape (..., 3)
    command : array_like, shape (..., 2)
        ``[v, omega]`` in m/s and rad/s.
    dt : float
        Time step, s.
    """
    p = as_array("pose", pose, finite=True)
    u = as_array("command", command, finite=True)
    if p.ndim == 0 or p.shape[-1] != 3:
        raise ValueError(f"pose must have shape (..., 3), got {p.shape}")
    if u.ndim == 0 or u.shape[-1] != 2:
        raise ValueError(f"command must have shape (..., 2), got {u.shape}")
    dt = check_positive("dt", dt)
    v, w = u[..., 0], u[..., 1]
    th = p[..., 2]
    return np.stack(
        [p[..., 0] + v * dt * np.cos(th), p[..., 1] + v * dt * np.sin(th), wrap_angle(th + w * dt)],
        -1,
    )


def sqrt_psd(c: np.ndarray) -> np.ndarray:
    """A matrix ``L`` with ``L L^T = c`` for a symmetric PSD ``c`` (zero noise allowed)."""
    eig, vec = np.linalg.eigh(c)
    return vec * np.sqrt(np.clip(eig, 0.0, None))


def _range_bearing(fiducials: np.ndarray, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = fiducials - pose[:2]
    return np.hypot(d[:, 0], d[:, 1]), wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - pose[2])


@dataclass(frozen=True)
class FiducialRun:
    """A whole recorded run of the fiducial robot: plain arrays, picklable, saved as ``.npz``.

    Attributes
    ----------
    commands : ndarray, shape (T, 2)
        ``[v, omega]`` applied at step ``t`` (moves ``true_poses[t]`` to ``true_poses[t+1]``).
    measurements : ndarray, shape (M, 4)
        Rows ``[t, range, bearing, id]``: fiducial ``id`` seen from ``true_poses[t+1]``,
        i.e. after the motion of step ``t``.
    true_poses : ndarray, shape (T+1, 3)
        Ground truth, starting at ``x0``.
    fiducials : ndarray, shape (K, 2)
        True fiducial positions, metres.
    dt : float
    Q : ndarray, shape (3, 3)
        Motion noise covariance per step.
    Qt : ndarray, shape (2, 2)
        Measurement noise covariance of ``[range, bearing]``.
    x0 : ndarray, shape (3,)
    """

    commands: np.ndarray
    measurements: np.ndarray
    true_poses: np.ndarray
    fiducials: np.ndarray
    dt: float
    Q: np.ndarray
    Qt: np.ndarray
    x0: np.ndarray

    @property
    def n_steps(self) -> int:
        return int(self.commands.shape[0])

    @property
    def n_fiducials(self) -> int:
        return int(self.fiducials.shape[0])

    def observations(self, t: int) -> np.ndarray:
        """Rows ``[range, bearing, id]`` seen after step ``t``, shape ``(k, 3)``."""
        rows = self.measurements[self.measurements[:, 0] == t]
        return rows[:, 1:].copy()

    def robot(self) -> FiducialRobot:
        """A fresh :class:`FiducialRobot` replaying this run from its start."""
        return FiducialRobot._from_run(self)

    def save(self, path) -> Path:
        """Write the run to ``path`` (``.npz``) and return the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "wb") as fh:
            np.savez_compressed(
                fh,
                commands=self.commands,
                measurements=self.measurements,
                true_poses=self.true_poses,
                fiducials=self.fiducials,
                dt=np.float64(self.dt),
                Q=self.Q,
                Qt=self.Qt,
                x0=self.x0,
            )
        return path


class FiducialRobot:
    """The fiducial robot of the FastSLAM lab, driven like a MATLAB ``Robot.m``.

    Use it as::

        robot = FiducialRobot(seed=0)
        while robot.run():
            u = robot.input()          # [v, omega] of the step just taken
            z = robot.measurement()    # (k, 3) rows [range, bearing, id] at the new pose

    Parameters
    ----------
    seed : int
        Seed of the ``numpy.random.Generator`` that draws the whole run.
    n_steps : int
        Number of steps; ``run()`` returns False after that many.
    dt : float
        Time step, s.
    Q : array_like (3, 3), optional
        Motion noise covariance per step (positive semi-definite; zeros give the
        exact unicycle). Default :data:`Q_DEFAULT`.
    Qt : array_like (2, 2), optional
        Measurement noise covariance (positive semi-definite). Default :data:`QT_DEFAULT`.
    fov : float
        Total field of view, rad, in ``(0, 2 pi]``, centred on the heading.
    max_range : float
        Detection range, m.
    min_range : float
        Fiducials closer than this (m) are not detected.
    n_fiducials : int
        Number of fiducials (:func:`fiducial_layout`); ignored when ``fiducials`` is given.
    fiducials : array_like (K, 2), optional
        Explicit fiducial positions.
    x0 : array_like (3,), optional
        Start pose, default :data:`X0`.

    Attributes
    ----------
    true_poses : ndarray (n_steps + 1, 3)
        The true path, ground truth for grading.
    fiducials : ndarray (K, 2)
        The true fiducial positions.
    step : int
        Number of steps taken so far.
    """

    def __init__(
        self,
        seed: int = 0,
        n_steps: int = N_STEPS_DEFAULT,
        dt: float = DT,
        Q=None,
        Qt=None,
        fov: float = FOV_DEFAULT,
        max_range: float = MAX_RANGE_DEFAULT,
        min_range: float = MIN_RANGE_DEFAULT,
        n_fiducials: int = 5,
        fiducials=None,
        x0=None,
    ):
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
            raise TypeError(f"seed must be an int, got {type(seed).__name__}")
        if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
            raise ValueError(f"n_steps must be a positive integer, got {n_steps!r}")
        self.dt = check_positive("dt", dt)
        self.Q = check_covariance("Q", Q_DEFAULT if Q is None else Q, 3, definite=False)
        self.Qt = check_covariance("Qt", QT_DEFAULT if Qt is None else Qt, 2, definite=False)
        self.fov = check_positive("fov", fov)
        if self.fov > 2.0 * np.pi + 1e-12:
            raise ValueError(f"fov must be in (0, 2 pi], got {fov!r}")
        self.max_range = check_positive("max_range", max_range)
        self.min_range = check_positive("min_range", min_range, allow_zero=True)
        if self.min_range >= self.max_range:
            raise ValueError(f"min_range must be < max_range ({self.max_range}), got {min_range!r}")
        if fiducials is None:
            self.fiducials = fiducial_layout(n_fiducials)
        else:
            self.fiducials = as_array("fiducials", fiducials, ndim=2, finite=True).copy()
            if self.fiducials.shape[1] != 2 or self.fiducials.shape[0] < 1:
                raise ValueError(
                    f"fiducials must have shape (K, 2) with K >= 1, got {self.fiducials.shape}"
                )
        self.x0 = X0.copy() if x0 is None else as_array("x0", x0, shape=(3,), finite=True).copy()
        self.x0[2] = wrap_angle(self.x0[2])
        self.seed = int(seed)
        self.n_steps = int(n_steps)
        self._simulate(np.random.default_rng(self.seed))
        self.step = 0

    # -- simulation, done once ------------------------------------------------
    def _simulate(self, rng: np.random.Generator) -> None:
        T = self.n_steps
        commands = route_command(np.arange(T) * self.dt)
        process = rng.standard_normal((T, 3)) @ sqrt_psd(self.Q).T
        poses = np.empty((T + 1, 3))
        poses[0] = self.x0
        sensor = sqrt_psd(self.Qt)
        rows = []
        for t in range(T):  # the robot is one pose: a loop over time is the model
            nxt = unicycle(poses[t], commands[t], self.dt) + process[t]
            nxt[2] = wrap_angle(nxt[2])
            poses[t + 1] = nxt
            r, b = _range_bearing(self.fiducials, nxt)
            visible = (r >= self.min_range) & (r <= self.max_range) & (np.abs(b) <= 0.5 * self.fov)
            ids = np.flatnonzero(visible)
            noise = rng.standard_normal((len(ids), 2)) @ sensor.T
            z = np.column_stack(
                [np.full(len(ids), t), r[ids] + noise[:, 0], wrap_angle(b[ids] + noise[:, 1]), ids]
            )
            rows.append(z)
        self._commands = commands
        self.true_poses = poses
        self._measurements = np.vstack(rows) if rows else np.empty((0, 4))

    @classmethod
    def _from_run(cls, run: FiducialRun) -> FiducialRobot:
        robot = cls.__new__(cls)
        robot.dt = float(run.dt)
        robot.Q = np.array(run.Q, dtype=float)
        robot.Qt = np.array(run.Qt, dtype=float)
        robot.fov = float("nan")  # not recorded; the measurements already reflect it
        robot.max_range = float("nan")
        robot.min_range = float("nan")
        robot.fiducials = np.array(run.fiducials, dtype=float)
        robot.x0 = np.array(run.x0, dtype=float)
        robot.seed = -1
        robot.n_steps = run.n_steps
        robot._commands = np.array(run.commands, dtype=float)
        robot.true_poses = np.array(run.true_poses, dtype=float)
        rows = np.array(run.measurements, dtype=float).reshape(-1, 4)
        robot._measurements = rows[np.argsort(rows[:, 0], kind="stable")]
        robot.step = 0
        return robot

    # -- the Robot.m interface ---------------------------------------------------
    @property
    def n_fiducials(self) -> int:
        return int(self.fiducials.shape[0])

    def run(self) -> bool:
        """Advance one step; return False (and do nothing) once all ``n_steps`` are done."""
        if self.step >= self.n_steps:
            return False
        self.step += 1
        return True

    def _require_started(self, what: str) -> int:
        if self.step == 0:
            raise RuntimeError(f"call run() before {what}(): the robot has not moved yet")
        return self.step - 1

    def input(self) -> np.ndarray:
        """The command ``[v, omega]`` (m/s, rad/s) of the step ``run()`` just took, shape (2,)."""
        return self._commands[self._require_started("input")].copy()

    def measurement(self) -> np.ndarray:
        """Visible fiducials at the current pose: ``(k, 3)`` rows ``[range, bearing, id]``.

        Range in metres, bearing in radians wrapped to ``[-pi, pi)`` (counter-clockwise
        from the heading), id the fiducial's index as a float. ``k`` may be 0.
        """
        t = self._require_started("measurement")
        lo, hi = np.searchsorted(self._measurements[:, 0], [t, t + 1], side="left")
        return self._measurements[lo:hi, 1:].copy()

    @property
    def pose(self) -> np.ndarray:
        """The current true pose (ground truth, not for the filter)."""
        return self.true_poses[self.step].copy()

    def reset(self) -> None:
        """Go back to the start of the (same) run."""
        self.step = 0

    def to_run(self) -> FiducialRun:
        """The whole run as a :class:`FiducialRun` of plain arrays."""
        return FiducialRun(
            commands=self._commands.copy(),
            measurements=self._measurements.copy(),
            true_poses=self.true_poses.copy(),
            fiducials=self.fiducials.copy(),
            dt=float(self.dt),
            Q=self.Q.copy(),
            Qt=self.Qt.copy(),
            x0=self.x0.copy(),
        )


def as_robot(robot_or_run) -> FiducialRobot:
    """A :class:`FiducialRobot` for a robot (as is), a :class:`FiducialRun` or a ``.npz`` path.

    A run or a path is replayed from its start; a robot continues from its current step.
    """
    if isinstance(robot_or_run, FiducialRobot):
        return robot_or_run
    if isinstance(robot_or_run, FiducialRun):
        return robot_or_run.robot()
    if isinstance(robot_or_run, (str, Path)):
        return load_run(robot_or_run).robot()
    raise TypeError(
        "robot_or_run must be a FiducialRobot, a FiducialRun or a path to a .npz run, "
        f"got {type(robot_or_run).__name__}"
    )


def write_run(path, seed: int = 0, **robot_kwargs) -> Path:
    """Simulate a run with ``FiducialRobot(seed=seed, **robot_kwargs)``; save it as ``.npz``.

    Returns the path written. ``robolab data`` calls ``write_run(data_dir / "fastslam.npz")``.
    """
    return FiducialRobot(seed=seed, **robot_kwargs).to_run().save(path)


_RUN_KEYS = ("commands", "measurements", "true_poses", "fiducials", "dt", "Q", "Qt", "x0")


def load_run(path) -> FiducialRun:
    """Read a run written by :func:`write_run`; a missing file or key raises a clear error."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"fiducial run {path} does not exist (make it with robolab data)")
    try:
        data = np.load(path, allow_pickle=False)
    except Exception as exc:  # not a zip, truncated, or an object array
        raise ValueError(f"{path} is not a readable .npz fiducial run: {exc}") from exc
    with data:
        missing = [k for k in _RUN_KEYS if k not in data.files]
        if missing:
            raise ValueError(f"{path} is not a fiducial run: missing {', '.join(missing)}")
        arrays = {k: np.array(data[k]) for k in _RUN_KEYS}
    T = arrays["commands"].shape[0] if arrays["commands"].ndim == 2 else -1
    shapes_ok = (
        arrays["commands"].ndim == 2
        and arrays["commands"].shape[1] == 2
        and arrays["measurements"].ndim == 2
        and arrays["measurements"].shape[1] == 4
        and arrays["true_poses"].shape == (T + 1, 3)
        and arrays["fiducials"].ndim == 2
        and arrays["fiducials"].shape[1] == 2
        and arrays["Q"].shape == (3, 3)
        and arrays["Qt"].shape == (2, 2)
        and arrays["x0"].shape == (3,)
        and arrays["dt"].shape == ()
    )
    if not shapes_ok:
        raise ValueError(
            f"{path}: arrays have unexpected shapes { ({k: v.shape for k, v in arrays.items()}) }"
        )
    return FiducialRun(
        commands=arrays["commands"].astype(float),
        measurements=arrays["measurements"].astype(float),
        true_poses=arrays["true_poses"].astype(float),
        fiducials=arrays["fiducials"].astype(float),
        dt=float(arrays["dt"]),
        Q=arrays["Q"].astype(float),
        Qt=arrays["Qt"].astype(float),
        x0=arrays["x0"].astype(float),
    )
