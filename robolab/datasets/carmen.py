"""CARMEN log files (``.log`` or ``.log.gz``): odometry, laser scans and corrected poses.

A CARMEN log is text, one message a line, the first token naming the message.
The fields of the messages read here (CARMEN's ``logger`` formats):

``ODOM x y theta tv rv accel timestamp host logger_timestamp``
    Wheel odometry: the robot's pose in the odometry frame and its velocities.
``FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta timestamp host logger_timestamp``
    Front laser (``RLASER``: rear) of the old format: ``n`` ranges in metres, the
    laser's pose ``x y theta`` (in a *corrected* log: the corrected pose in the map
    frame) and the robot's odometry pose. No beam geometry: ``n`` beams evenly over
    180 degrees starting at -90 degrees (1 degree apart for 180 or 181 beams),
    unless ``start_angle`` / ``angular_resolution`` say otherwise.
``ROBOTLASER1 laser_type start_angle fov angular_resolution max_range accuracy remission_mode
n r_1 .. r_n m e_1 .. e_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv
forward_safety_dist side_safety_dist turn_axis timestamp host logger_timestamp``
    The newer laser message with its own geometry (``ROBOTLASER2``: second laser).
``RAWLASER1 laser_type start_angle fov angular_resolution max_range accuracy remission_mode
n r_1 .. r_n m e_1 .. e_m timestamp host logger_timestamp``
    A laser without poses (``RAWLASER2`` .. ``RAWLASER4``).
``TRUEPOS true_x true_y true_theta odom_x odom_y odom_theta timestamp host logger_timestamp``
    Simulator ground truth.
``PARAM name value host timestamp``
    A parameter (kept as text).

Other lines (``#`` comments, ``NEFF``, ``SYNC``, ...) are skipped; a file with no
message at all is an error, as are stamps that collapse (see :func:`read_carmen`). Times are the
``timestamp`` field (seconds), not the logger's; messages keep the log's order (the
Intel log has four scans whose stamps step back).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robolab.bag import PoseTrack, Scans
from robolab.datasets.textlog import text_lines

__all__ = ["CarmenError", "CarmenLaser", "CarmenLog", "read_carmen"]

_OLD_LASERS = ("FLASER", "RLASER")
_NEW_LASERS = ("ROBOTLASER1", "ROBOTLASER2")
_RAW_LASERS = ("RAWLASER1", "RAWLASER2", "RAWLASER3", "RAWLASER4")


class CarmenError(ValueError):
    """A CARMEN log line does not have the fields its message type needs."""


@dataclass(frozen=True, eq=False)
class CarmenLaser:
    """The scans of one laser message type.

    Attributes
    ----------
    scans : robolab.bag.Scans
        Stamps, ranges ``(T, B)``, beam angles in the laser frame, range limits.
    laser_poses : numpy.ndarray, shape (T, 3), or None
        The laser's pose with each scan (FLASER ``x y theta``, ROBOTLASER1
        ``laser_x ..``; the corrected pose in a corrected log); None for RAWLASER.
    robot_poses : numpy.ndarray, shape (T, 3), or None
        The robot's (odometry) pose with each scan.
    """

    scans: Scans
    laser_poses: np.ndarray | None
    robot_poses: np.ndarray | None

    def __len__(self) -> int:
        return len(self.scans)


@dataclass(frozen=True, eq=False)
class CarmenLog:
    """What a CARMEN log holds, as arrays.

    Attributes
    ----------
    path : Path
    odometry : robolab.bag.PoseTrack or None
        ``ODOM`` poses (frame ``odom`` -> ``base_link``).
    velocities : numpy.ndarray, shape (T, 2), or None
        ``ODOM`` ``(tv, rv)``, m/s and rad/s.
    lasers : dict of str to CarmenLaser
        One entry per laser message type present (``"FLASER"``, ``"ROBOTLASER1"``, ...).
    truth : robolab.bag.PoseTrack or None
        ``TRUEPOS`` poses.
    params : dict of str to str
    """

    path: Path
    odometry: PoseTrack | None
    velocities: np.ndarray | None
    lasers: dict[str, CarmenLaser] = field(default_factory=dict)
    truth: PoseTrack | None = None
    params: dict[str, str] = field(default_factory=dict)

    def laser(self, name: str | None = None) -> CarmenLaser:
        """The scans of message type ``name``; default the only (or FLASER / ROBOTLASER1) one."""
        if name is None:
            for preferred in ("FLASER", "ROBOTLASER1"):
                if preferred in self.lasers:
                    return self.lasers[preferred]
            if len(self.lasers) == 1:
                return next(iter(self.lasers.values()))
            raise CarmenError(
                f"{self.path}: name the laser, one of {sorted(self.lasers) or 'none (no scans)'}"
            )
        if name not in self.lasers:
            raise CarmenError(f"{self.path}: no {name} messages; lasers: {sorted(self.lasers)}")
        return self.lasers[name]


def _check_stamps(path: Path, what: str, stamps: np.ndarray) -> None:
    """CarmenError when many messages share few stamps (printed with too few digits)."""
    distinct = np.unique(stamps).size
    if stamps.size >= 3 and 2 * distinct < stamps.size:
        raise CarmenError(
            f"{path}: {stamps.size} {what} messages have only {distinct} distinct timestamps "
            f"(e.g. {float(stamps[0])}): the log's stamps were printed with too few digits "
            "(as %g does); write them with microseconds (%.6f) to read this log"
        )


def _numbers(path: Path, lineno: int, tokens: list[str], what: str) -> np.ndarray:
    try:
        return np.array(tokens, dtype=float)
    except ValueError as exc:
        raise CarmenError(f"{path}:{lineno}: {what}: {exc}") from exc


def _need(path: Path, lineno: int, tokens: list[str], n: int, what: str) -> None:
    if len(tokens) < n:
        raise CarmenError(
            f"{path}:{lineno}: {what} needs at least {n} fields after its name, got {len(tokens)}"
        )


def _old_laser(path, lineno, tok, name):
    """FLASER / RLASER fields: ranges, laser pose, odometry pose, timestamp."""
    _need(path, lineno, tok, 1, name)
    n = int(_numbers(path, lineno, tok[:1], f"{name} beam count")[0])
    _need(path, lineno, tok, n + 8, name)
    v = _numbers(path, lineno, tok[1 : n + 8], name)
    return {"ranges": v[:n], "laser": v[n : n + 3], "robot": v[n + 3 : n + 6], "t": v[n + 6]}


def _new_laser(path, lineno, tok, name, with_poses):
    """ROBOTLASER / RAWLASER fields (see the module docstring)."""
    _need(path, lineno, tok, 8, name)
    head = _numbers(path, lineno, tok[:8], name)
    n = int(head[7])
    _need(path, lineno, tok, 8 + n + 1, name)
    ranges = _numbers(path, lineno, tok[8 : 8 + n], f"{name} ranges")
    m = int(_numbers(path, lineno, tok[8 + n : 9 + n], f"{name} remission count")[0])
    rest_at = 9 + n + m
    tail = 12 if with_poses else 1  # poses (6), tv rv and 3 safety fields (5), timestamp
    _need(path, lineno, tok, rest_at + tail, name)
    rest = _numbers(path, lineno, tok[rest_at : rest_at + tail], name)
    out = {"ranges": ranges, "start": head[1], "res": head[3], "max": head[4], "t": rest[-1]}
    if with_poses:
        out["laser"], out["robot"] = rest[0:3], rest[3:6]
    return out


def _scans(path, name, rows, start_angle, angular_resolution, max_range) -> CarmenLaser:
    lengths = {r["ranges"].size for r in rows}
    if len(lengths) > 1:
        raise CarmenError(f"{path}: {name} scans have different lengths: {sorted(lengths)}")
    n = lengths.pop()
    if n == 0:
        raise CarmenError(f"{path}: {name} scans have no beams")
    ranges = np.stack([r["ranges"] for r in rows])
    if "start" in rows[0]:  # the message carries its geometry
        start = rows[0]["start"] if start_angle is None else start_angle
        res = rows[0]["res"] if angular_resolution is None else angular_resolution
        rmax = max(r["max"] for r in rows) if max_range is None else max_range
    else:  # FLASER: 180 degrees, first beam at -90 degrees
        start = -np.pi / 2 if start_angle is None else start_angle
        res = np.pi / (n - n % 2) if angular_resolution is None else angular_resolution
        rmax = float(np.nanmax(ranges)) if max_range is None else max_range
    scans = Scans(
        stamps=np.array([r["t"] for r in rows]),
        ranges=ranges,
        angles=start + res * np.arange(n),
        range_min=0.0,
        range_max=float(rmax),
        frame_id=name,
    )
    laser = np.stack([r["laser"] for r in rows]) if "laser" in rows[0] else None
    robot = np.stack([r["robot"] for r in rows]) if "robot" in rows[0] else None
    return CarmenLaser(scans, laser, robot)


def read_carmen(path, *, start_angle=None, angular_resolution=None, max_range=None) -> CarmenLog:
    """Read a CARMEN log (plain or gzip-compressed).

    Parameters
    ----------
    path : str or Path
    start_angle, angular_resolution : float, optional
        Beam geometry (radians) for every laser; default what the message says
        (ROBOTLASER, RAWLASER) or, for FLASER / RLASER, which carry none: first
        beam at -90 degrees, 180 degrees in all.
    max_range : float, optional
        ``range_max`` of the scans; default the message's maximum range or, for
        FLASER, the largest reading in the log (the laser's no-return value, e.g.
        81.83 m in the Intel log), so that max-range readings are not hits.

    Returns
    -------
    CarmenLog

    Raises
    ------
    FileNotFoundError
    CarmenError
        A line with too few or non-numeric fields (the message names the line); bytes
        that are not text; a truncated or corrupt ``.gz``; a file without any message
        (empty, or comments only); timestamps that collapse (fewer distinct stamps
        than half the messages of a kind: printed with ``%g``, ``1.13486e+09``, every
        stamp of a run is one of two or three values).
    """
    path = Path(path)
    odom, truth, params = [], [], {}
    lasers: dict[str, list] = {}
    lines = 0
    for lineno, line in text_lines(path, CarmenError, "CARMEN log"):
        lines = lineno
        tok = line.split()
        if not tok:
            continue
        name, rest = tok[0], tok[1:]
        if name == "ODOM":
            _need(path, lineno, rest, 7, name)
            odom.append(_numbers(path, lineno, rest[:7], name))
        elif name == "TRUEPOS":
            _need(path, lineno, rest, 7, name)
            truth.append(_numbers(path, lineno, rest[:7], name))
        elif name == "PARAM" and len(rest) >= 2:
            params[rest[0]] = rest[1]
        elif name in _OLD_LASERS:
            lasers.setdefault(name, []).append(_old_laser(path, lineno, rest, name))
        elif name in _NEW_LASERS or name in _RAW_LASERS:
            row = _new_laser(path, lineno, rest, name, name in _NEW_LASERS)
            lasers.setdefault(name, []).append(row)
    if not (odom or truth or lasers):
        raise CarmenError(
            f"{path}: no CARMEN messages (ODOM, TRUEPOS, FLASER, ROBOTLASER1, ...) in "
            + ("an empty file" if lines == 0 else f"its {lines} line(s)")
        )
    for what, rows, at in (("ODOM", odom, 6), ("TRUEPOS", truth, 6)):
        if rows:
            _check_stamps(path, what, np.array([r[at] for r in rows]))
    for name, rows in lasers.items():
        _check_stamps(path, name, np.array([r["t"] for r in rows]))
    odometry = velocities = None
    if odom:
        a = np.array(odom)
        odometry = PoseTrack(a[:, 6], a[:, :3], "odom", "base_link")
        velocities = a[:, 3:5]
    true_track = None
    if truth:
        a = np.array(truth)
        true_track = PoseTrack(a[:, 6], a[:, :3], "map", "base_link")
    return CarmenLog(
        path=path,
        odometry=odometry,
        velocities=velocities,
        lasers={
            k: _scans(path, k, rows, start_angle, angular_resolution, max_range)
            for k, rows in lasers.items()
        },
        truth=true_track,
        params=params,
    )
