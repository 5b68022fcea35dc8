"""ROS bag reading (ROS1 and ROS2) and ROS1 writing, on the pure-Python ``rosbags`` library.

Reading gives typed numpy views of the messages the labs need:

* :class:`Scans` -- every ``sensor_msgs/LaserScan`` of one topic, ranges ``(T, B)``;
* :class:`PoseTrack` -- odometry (``nav_msgs/Odometry``), ground truth
  (``geometry_msgs/PoseStamped``) or one TF edge, poses ``(T, 3)`` with interpolation;
* :class:`TfTree` -- every edge seen on ``/tf`` and ``/tf_static``, with chained lookups.

Writing (:class:`BagWriter`) produces ROS1 bags v2.0, which is what the simulator
bundles. No ROS installation is needed.

Conventions
-----------
* Times are seconds as float64 (``sec + nanosec / 1e9``). The typed views use the
  messages' *header* stamps; :meth:`BagReader.messages` yields the bag's record time.
* Poses are ``(x, y, theta)`` in metres and radians, ``theta`` wrapped to
  ``[-pi, pi)``; only the planar part (x, y, yaw) of 3D messages is kept.
* LaserScan ranges are kept raw; :attr:`Scans.valid` says which are real returns
  (0, inf, NaN and values outside ``[range_min, range_max]`` are not).
* Topic names match with or without the leading slash (``"base_scan"`` finds
  ``/base_scan``), as the AMCL project's ``processBag`` writes them.
* TF frame ids are compared without a leading slash (``/camera_frame`` is
  ``camera_frame``), as tf2 does.

Errors
------
A missing file raises :class:`FileNotFoundError`; anything else wrong with a bag
(truncated, corrupt, missing topic, wrong message type, no or inconsistent scans)
raises :class:`BagError`, whose message names the file. Typed views read all their
messages eagerly, so a bag that breaks half-way raises instead of returning the
first half as if it were the whole.
"""

from __future__ import annotations

import math
import os
import warnings
from collections import deque
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from robolab.geometry import (
    angle_diff,
    compose,
    inverse,
    quaternion_from_yaw,
    transform_points,
    wrap_angle,
    yaw_from_quaternion,
)
from robolab.validation import as_array

__all__ = [
    "BagError",
    "TopicInfo",
    "Scans",
    "PoseTrack",
    "TfTree",
    "BagReader",
    "BagWriter",
    "laser_pose_in_base",
    "LASER_SCAN",
    "ODOMETRY",
    "POSE_STAMPED",
    "TF_MESSAGE",
]

#: Message type names as ``rosbags`` spells them (ROS1 types get the ``/msg/`` part too).
LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"

# Noetic's tf2_msgs/TFMessage; rosbags' ROS1 store lacks it. md5 94810edda583a504dfda3829e70d7eec.
_TF_MESSAGE_DEF = "geometry_msgs/TransformStamped[] transforms"

# A transform whose samples differ by less than this (metres / radians) is rigid.
_RIGID_TOL = 1e-6


class BagError(ValueError):
    """A bag cannot be read as asked: corrupt or truncated file, missing topic, bad content."""


# ---------------------------------------------------------------------------------
# typed views
# ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag.

    Attributes
    ----------
    name : str
        Topic name as recorded, e.g. ``"/scan"``.
    msgtype : str
        Message type in rosbags' spelling, e.g. ``"sensor_msgs/msg/LaserScan"``
        (types of several connections are joined with ``"|"`` if they differ).
    count : int
        Number of messages.
    """

    name: str
    msgtype: str
    count: int


@dataclass(frozen=True, eq=False)
class Scans:
    """All ``sensor_msgs/LaserScan`` messages of one topic.

    Attributes
    ----------
    stamps : numpy.ndarray, shape (T,)
        Header stamps, seconds.
    ranges : numpy.ndarray, shape (T, B)
        Ranges in metres, raw as recorded (0, inf and NaN included).
    angles : numpy.ndarray, shape (B,)
        Beam angles in the laser frame, ``angle_min + i * angle_increment``, radians
        (not wrapped: a 361-beam scan from -pi to pi keeps both ends).
    range_min, range_max : float
        Valid range interval, metres.
    frame_id : str
        The laser's frame (``header.frame_id``).
    """

    stamps: np.ndarray
    ranges: np.ndarray
    angles: np.ndarray
    range_min: float
    range_max: float
    frame_id: str

    def __post_init__(self):
        stamps = as_array("stamps", self.stamps, ndim=1, finite=True)
        ranges = as_array("ranges", self.ranges, ndim=2)
        angles = as_array("angles", self.angles, ndim=1, finite=True)
        if ranges.shape != (stamps.size, angles.size):
            raise ValueError(
                f"ranges must have shape (T, B) = ({stamps.size}, {angles.size}) to match stamps "
                f"and angles, "
                f"got {ranges.shape}"
            )
        rmin, rmax = float(self.range_min), float(self.range_max)
        if not (np.isfinite(rmin) and np.isfinite(rmax) and 0 <= rmin < rmax):
            raise ValueError(
                f"range_min and range_max must be finite with 0 <= range_min < range_max, "
                f"got {rmin}, {rmax}"
            )
        object.__setattr__(self, "stamps", stamps)
        object.__setattr__(self, "ranges", ranges)
        object.__setattr__(self, "angles", angles)
        object.__setattr__(self, "range_min", rmin)
        object.__setattr__(self, "range_max", rmax)

    def __len__(self) -> int:
        return self.stamps.size

    @property
    def beams(self) -> int:
        """Number of beams per scan ``B``."""
        return self.angles.size

    @property
    def valid(self) -> np.ndarray:
        """``(T, B)`` bool: real returns (finite, > 0, within ``[range_min, range_max)``).

        0, inf and NaN mean "no return" and are never turned into hits. A reading
        of exactly ``range_max`` is a max-range reading (a failed return, the beam
        model's ``p_max``), not an obstacle at ``range_max``: AMCL and gmapping
        skip it too.
        """
        r = self.ranges
        with np.errstate(invalid="ignore"):
            return np.isfinite(r) & (r > 0) & (r >= self.range_min) & (r < self.range_max)

    def endpoints(self, i: int, laser_pose=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Endpoints of the valid beams of scan ``i``.

        Parameters
        ----------
        i : int
            Scan index (negative indices count from the end).
        laser_pose : array_like, shape (3,)
            Pose of the laser in some frame, e.g. ``compose(robot_pose, laser_pose_in_base(...))``
            for the map frame. Default: the laser frame itself.

        Returns
        -------
        numpy.ndarray, shape (P, 2)
            ``(x, y)`` of each valid beam's endpoint in the frame ``laser_pose`` is given in.
        """
        if not isinstance(i, (int, np.integer)) or not -len(self) <= i < len(self):
            raise IndexError(
                f"i must be an integer scan index in [-{len(self)}, {len(self)}), got {i!r}"
            )
        pose = as_array("laser_pose", laser_pose, shape=(3,), finite=True)
        ok = self.valid[i]
        r, a = self.ranges[i, ok], self.angles[ok]
        return transform_points(np.stack([r * np.cos(a), r * np.sin(a)], -1), pose)


@dataclass(frozen=True, eq=False)
class PoseTrack:
    """A time series of planar poses: odometry, ground truth, or one TF edge.

    Attributes
    ----------
    stamps : numpy.ndarray, shape (T,)
        Seconds, as recorded (not necessarily unique or sorted).
    poses : numpy.ndarray, shape (T, 3)
        ``(x, y, theta)`` of ``child_frame_id`` in ``frame_id``; theta wrapped to [-pi, pi).
    frame_id : str
        Parent frame.
    child_frame_id : str
        Child frame (empty for a PoseStamped, whose child is implicit).

    Notes
    -----
    :meth:`at` interpolates on the samples sorted by time, with samples that share
    a stamp replaced by their *average* (mean x, y; circular mean of theta). The
    Olin ``/map_pose`` has about a quarter of its stamps carrying two camera
    detections 1.5 cm apart; averaging them is the least-squares estimate, where
    keeping either one would be an arbitrary choice.
    """

    stamps: np.ndarray
    poses: np.ndarray
    frame_id: str = ""
    child_frame_id: str = ""

    def __post_init__(self):
        stamps = as_array("stamps", self.stamps, ndim=1, finite=True)
        poses = as_array("poses", self.poses, shape=(stamps.size, 3), finite=True).copy()
        if stamps.size == 0:
            raise ValueError("stamps must hold at least one sample, got 0")
        poses[:, 2] = wrap_angle(poses[:, 2])
        object.__setattr__(self, "stamps", stamps)
        object.__setattr__(self, "poses", poses)

    def __len__(self) -> int:
        return self.stamps.size

    @property
    def x(self) -> np.ndarray:
        """``(T,)`` x, metres."""
        return self.poses[:, 0]

    @property
    def y(self) -> np.ndarray:
        """``(T,)`` y, metres."""
        return self.poses[:, 1]

    @property
    def theta(self) -> np.ndarray:
        """``(T,)`` heading, radians in [-pi, pi)."""
        return self.poses[:, 2]

    @property
    def is_constant(self) -> bool:
        """True when every sample equals the first (a rigid mount published repeatedly)."""
        d = self.poses - self.poses[0]
        return bool(
            np.all(np.abs(d[:, :2]) < _RIGID_TOL)
            and np.all(np.abs(angle_diff(self.poses[:, 2], self.poses[0, 2])) < _RIGID_TOL)
        )

    @cached_property
    def _knots(self) -> tuple[np.ndarray, np.ndarray]:
        """Sorted unique stamps and their (averaged) poses, the interpolation knots."""
        order = np.argsort(self.stamps, kind="stable")
        s, p = self.stamps[order], self.poses[order]
        u, start, counts = np.unique(s, return_index=True, return_counts=True)
        if u.size == s.size:
            return s, p
        xy = np.add.reduceat(p[:, :2], start, axis=0) / counts[:, None]
        th = np.arctan2(
            np.add.reduceat(np.sin(p[:, 2]), start), np.add.reduceat(np.cos(p[:, 2]), start)
        )
        return u, np.column_stack([xy, wrap_angle(th)])

    def at(self, t) -> np.ndarray:
        """Pose at time(s) ``t`` by linear interpolation (shortest arc for theta).

        Parameters
        ----------
        t : float or array_like, shape (K,)
            Seconds, within ``[stamps.min(), stamps.max()]``.

        Returns
        -------
        numpy.ndarray, shape (3,) for a scalar ``t``, (K, 3) otherwise

        Raises
        ------
        ValueError
            If any ``t`` lies outside the recorded time range: the track does not
            extrapolate silently.
        """
        tt = as_array("t", t, ndim=(0, 1), finite=True)
        scalar = tt.ndim == 0
        tt = np.atleast_1d(tt)
        s, p = self._knots
        outside = (tt < s[0]) | (tt > s[-1])
        if np.any(outside):
            raise ValueError(
                f"t = {tt[outside][0]!r} s is outside the time range [{s[0]!r}, {s[-1]!r}] s of "
                f"{self.frame_id or '?'} -> {self.child_frame_id or '?'}; "
                "PoseTrack.at does not extrapolate"
            )
        if s.size == 1:
            out = np.repeat(p, tt.size, axis=0)
        else:
            i = np.clip(np.searchsorted(s, tt, side="right") - 1, 0, s.size - 2)
            f = (tt - s[i]) / (s[i + 1] - s[i])
            xy = p[i, :2] + f[:, None] * (p[i + 1, :2] - p[i, :2])
            th = wrap_angle(p[i, 2] + f * angle_diff(p[i + 1, 2], p[i, 2]))
            out = np.column_stack([xy, th])
        return out[0] if scalar else out

    #: The issue's name for :meth:`at`.
    pose_at = at


def _frame(name: str) -> str:
    # tf2 ignores a leading slash in frame ids (ROS1 tf used "/odom").
    return name.lstrip("/")


class TfTree:
    """Transforms between frames, from every edge seen on ``/tf`` and ``/tf_static``.

    The edges may form several trees (the Olin bag has odom -> base_link ->
    base_laser_link, map -> odom from a filter, and a camera's tag frames).

    Parameters
    ----------
    edges : mapping of (parent, child) -> PoseTrack
        Each edge's poses of ``child`` in ``parent`` over time.
    static : iterable of (parent, child)
        Edges that hold at all times (from ``/tf_static``). An edge with a single
        sample is static too.
    """

    def __init__(
        self, edges: Mapping[tuple[str, str], PoseTrack], static: Iterable[tuple[str, str]] = ()
    ):
        self._edges: dict[tuple[str, str], PoseTrack] = {}
        for key, track in edges.items():
            if not (
                isinstance(key, tuple) and len(key) == 2 and all(isinstance(k, str) for k in key)
            ):
                raise TypeError(f"edges keys must be (parent, child) string pairs, got {key!r}")
            if not isinstance(track, PoseTrack):
                raise TypeError(f"edges[{key!r}] must be a PoseTrack, got {type(track).__name__}")
            k = (_frame(key[0]), _frame(key[1]))
            if k in self._edges:
                raise ValueError(
                    f"edge {k[0]} -> {k[1]} given twice (frame ids differ only by a leading '/')"
                )
            self._edges[k] = track
        static = {(_frame(p), _frame(c)) for p, c in static}
        if unknown := static - self._edges.keys():
            raise ValueError(f"static edges {sorted(unknown)} are not in edges")
        self._static = frozenset(static | {k for k, v in self._edges.items() if len(v) == 1})
        self._adjacent: dict[str, list[tuple[str, tuple[str, str], bool]]] = {}
        for p, c in self._edges:
            self._adjacent.setdefault(p, []).append((c, (p, c), True))
            self._adjacent.setdefault(c, []).append((p, (p, c), False))

    def __repr__(self) -> str:
        return f"TfTree({len(self._edges)} edges: {', '.join(f'{p}->{c}' for p, c in self._edges)})"

    @property
    def edges(self) -> dict[tuple[str, str], PoseTrack]:
        """``{(parent, child): PoseTrack}`` for every edge (frame ids without a leading slash)."""
        return dict(self._edges)

    @property
    def static(self) -> frozenset[tuple[str, str]]:
        """Edges that hold at all times."""
        return self._static

    @property
    def frames(self) -> list[str]:
        """Every frame id, sorted."""
        return sorted(self._adjacent)

    def chain(self, parent: str, child: str) -> list[tuple[tuple[str, str], bool]]:
        """The edges from ``parent`` to ``child``: ``[(edge, forward), ...]``.

        ``forward`` is False when the edge is walked from its child to its parent.
        Raises :class:`BagError` for unknown frames or frames in different trees.
        """
        parent, child = _frame(parent), _frame(child)
        for role, f in (("parent", parent), ("child", child)):
            if f not in self._adjacent:
                raise BagError(
                    f"unknown {role} frame {f!r}; frames in the TF tree: "
                    f"{', '.join(self.frames) or 'none'}"
                )
        came: dict[str, tuple[str, tuple[str, str], bool] | None] = {parent: None}
        queue = deque([parent])
        while queue:  # breadth first: the shortest chain
            f = queue.popleft()
            if f == child:
                break
            for nxt, edge, forward in self._adjacent[f]:
                if nxt not in came:
                    came[nxt] = (f, edge, forward)
                    queue.append(nxt)
        if child not in came:
            raise BagError(
                f"no TF chain from {parent!r} to {child!r}: they are in different trees; "
                f"{parent!r} connects to {sorted(came)}"
            )
        steps = []
        f = child
        while came[f] is not None:
            prev, edge, forward = came[f]
            steps.append((edge, forward))
            f = prev
        return steps[::-1]

    def lookup(self, parent: str, child: str, t=None) -> np.ndarray:
        """Pose of ``child`` in ``parent``, chaining edges in either direction.

        Parameters
        ----------
        parent, child : str
            Frame ids (a leading slash is ignored).
        t : float, array_like (K,), or None
            Time(s) in seconds. Static edges apply at all times. ``None`` asks for a
            rigid transform: every edge on the chain must be static or constant
            over time (e.g. a laser mount published on ``/tf`` at every step).

        Returns
        -------
        numpy.ndarray, shape (3,) or (K, 3)

        Raises
        ------
        BagError
            Unknown frames, frames in different trees, ``t`` outside a dynamic
            edge's time range, or ``t=None`` with an edge that moves.
        """
        steps = self.chain(parent, child)
        shape = (3,) if t is None or np.ndim(t) == 0 else (np.size(t), 3)
        pose = np.zeros(shape)
        for (p, c), forward in steps:
            track = self._edges[(p, c)]
            if (p, c) in self._static:
                edge = track.poses[-1]  # latched: the last published value holds
            elif t is None:
                if not track.is_constant:
                    raise BagError(
                        f"edge {p} -> {c} changes over time; pass the time t to look it up"
                    )
                edge = track.poses[0]
            else:
                try:
                    edge = track.at(t)
                except ValueError as exc:
                    raise BagError(f"cannot look up edge {p} -> {c}: {exc}") from exc
            pose = compose(pose, edge if forward else inverse(edge))
        return np.broadcast_to(pose, shape).copy()


def laser_pose_in_base(
    tf: TfTree, laser_frame: str, base_frame: str = "base_link", t=None
) -> np.ndarray:
    """The laser's mounting pose: the ``base_frame -> laser_frame`` transform.

    Parameters
    ----------
    tf : TfTree
        From :meth:`BagReader.tf`.
    laser_frame : str
        The scans' ``frame_id``, e.g. ``"base_laser_link"``.
    base_frame : str
        The robot's body frame.
    t : float or None
        Time; ``None`` (default) requires a rigid mount (see :meth:`TfTree.lookup`).

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``(x, y, theta)`` of the laser in the base frame. The Olin Neato's laser is
        mounted backwards: ``(-0.1016, 0, -pi)``. A scan endpoint ``q`` in the laser
        frame is at ``transform_points(q, compose(robot_pose, laser_pose))`` in the world.
    """
    if not isinstance(tf, TfTree):
        raise TypeError(f"tf must be a TfTree (from BagReader.tf()), got {type(tf).__name__}")
    return tf.lookup(base_frame, laser_frame, t)


# ---------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------
def _stamps(msgs) -> np.ndarray:
    """Header stamps of messages, seconds (one vectorized conversion)."""
    t = np.array(
        [(m.header.stamp.sec, m.header.stamp.nanosec) for m in msgs], dtype=np.int64
    ).reshape(-1, 2)
    return t[:, 0] + t[:, 1] / 1e9


def _planar(rows) -> np.ndarray:
    """``(N, 7)`` rows of (x, y, z, qx, qy, qz, qw) -> ``(N, 3)`` planar poses."""
    a = np.asarray(rows, dtype=float).reshape(-1, 7)
    return np.column_stack(
        [a[:, 0], a[:, 1], yaw_from_quaternion(a[:, 3], a[:, 4], a[:, 5], a[:, 6])]
    )


def _pose_row(pose) -> tuple[float, ...]:
    p, q = pose.position, pose.orientation
    return (p.x, p.y, p.z, q.x, q.y, q.z, q.w)


class BagReader:
    """Read a ROS1 ``.bag`` file or a ROS2 bag (folder, ``.db3`` or ``.mcap``).

    Parameters
    ----------
    path : str or os.PathLike
        The bag. A ROS1 bag's name must end in ``.bag`` (that is how ``rosbags``
        tells the formats apart).
    progress : bool
        Show a tqdm progress bar while reading messages.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    BagError
        If the file is not a readable bag (truncated, corrupt header, unknown format).

    Examples
    --------
    >>> with BagReader("ac109_1_demo.bag") as bag:          # doctest: +SKIP
    ...     scans = bag.scans("/scan")
    ...     truth = bag.poses("/map_pose")
    ...     mount = laser_pose_in_base(bag.tf(), scans.frame_id)
    """

    def __init__(self, path, progress: bool = False):
        self.path = Path(path)
        self.progress = bool(progress)
        if not self.path.exists():
            raise FileNotFoundError(f"bag not found: {self.path}")
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        self._reader = None
        with self._wrap("cannot open bag"):
            reader = AnyReader([self.path], default_typestore=get_typestore(Stores.LATEST))
            reader.open()
            self._reader = reader
        try:
            self._topics = {
                name: TopicInfo(
                    name,
                    info.msgtype or "|".join(sorted({c.msgtype for c in info.connections})),
                    int(info.msgcount),
                )
                for name, info in reader.topics.items()
            }
            self._connections = list(reader.connections)
        except Exception as exc:
            self.close()
            raise BagError(f"{self.path}: cannot list the bag's topics: {exc}") from exc
        self._cache: dict[str, list] = {}

    # -- lifecycle --------------------------------------------------------------------
    def close(self) -> None:
        """Close the file (idempotent)."""
        reader, self._reader = self._reader, None
        self._cache = {}
        if reader is not None:
            reader.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"BagReader({str(self.path)!r}, {len(self._topics)} topics)"

    @contextmanager
    def _wrap(self, what: str):
        """Turn whatever the parsing layers raise into a BagError naming the file."""
        try:
            yield
        except (BagError, FileNotFoundError):
            raise
        except Exception as exc:
            hint = ""
            if self.path.is_file() and self.path.suffix != ".bag":
                with open(self.path, "rb") as fh:
                    if fh.read(13) == b"#ROSBAG V2.0\n":
                        hint = " (this is a ROS1 bag: its name must end in .bag)"
            raise BagError(f"{self.path}: {what}: {type(exc).__name__}: {exc}{hint}") from exc

    def _check_open(self):
        if self._reader is None:
            raise BagError(f"{self.path}: the bag is closed")
        return self._reader

    # -- topics and raw messages ------------------------------------------------------
    @property
    def topics(self) -> dict[str, TopicInfo]:
        """``{name: TopicInfo}`` for every topic, sorted by name."""
        return dict(self._topics)

    def _resolve(self, topic: str) -> str:
        if not isinstance(topic, str):
            raise TypeError(f"topic must be a str, got {type(topic).__name__}")
        alternative = topic[1:] if topic.startswith("/") else "/" + topic
        for name in (topic, alternative):
            if name in self._topics:
                return name
        raise BagError(
            f"{self.path}: no topic {topic!r}; topics in the bag: "
            f"{', '.join(self._topics) or 'none'}"
        )

    def _iterate(self, connections, desc: str):
        """Yield ``(connection, record_time_ns, message)`` in time order; errors wrapped."""
        reader = self._check_open()
        total = sum(c.msgcount for c in connections)
        with self._wrap(f"cannot read {desc}"):
            stream = reader.messages(connections=connections)
            if self.progress:
                from tqdm.auto import tqdm

                stream = tqdm(stream, total=total, desc=f"{self.path.name}: {desc}", unit="msg")
            for conn, timestamp, raw in stream:
                yield conn, timestamp, reader.deserialize(raw, conn.msgtype)

    def _supported(self, conn) -> bool:
        return conn.msgtype in self._check_open().typestore.fielddefs

    def messages(self, topics=None) -> Iterator[tuple[str, float, object]]:
        """Iterate over the messages of ``topics`` in time order, like ``processBag``.

        Parameters
        ----------
        topics : str, iterable of str, or None
            Topic names (leading slash optional); ``None`` means every topic.

        Yields
        ------
        topic : str
            The topic's name as recorded.
        stamp : float
            The bag's record time, seconds (header stamps are in the message).
        msg : object
            The deserialized message (a rosbags dataclass: ``msg.header.stamp.sec``,
            ``msg.ranges``, ``msg.transforms``, ...).

        Raises
        ------
        BagError
            A requested topic does not exist (the message lists those that do), or
            the file breaks while reading. A topic whose message type the bag's
            typestore cannot decode is skipped with a warning.
        """
        if topics is None:
            names = list(self._topics)
        else:
            names = [
                self._resolve(t) for t in ([topics] if isinstance(topics, str) else list(topics))
            ]
        selected = [c for c in self._connections if c.topic in set(names)]
        usable = []
        for conn in selected:
            if self._supported(conn):
                usable.append(conn)
            else:
                warnings.warn(
                    f"{self.path}: skipping topic {conn.topic!r}: message type "
                    f"{conn.msgtype!r} is not defined in the bag's typestore",
                    stacklevel=2,  # points at the caller of messages()
                )
        # Checks above run now, at the call; only the reading is lazy.
        return self._stream(usable)

    def _stream(self, connections) -> Iterator[tuple[str, float, object]]:
        if not connections:
            return
        desc = ", ".join(sorted({c.topic for c in connections}))
        for conn, timestamp, msg in self._iterate(connections, desc):
            yield conn.topic, timestamp / 1e9, msg

    def _read_all(self, topic: str, msgtypes: tuple[str, ...], what: str) -> tuple[str, list]:
        """Every message of ``topic``, read eagerly; the topic must have one of ``msgtypes``."""
        name = self._resolve(topic)
        conns = [c for c in self._connections if c.topic == name]
        for conn in conns:
            if conn.msgtype not in msgtypes:
                raise BagError(
                    f"{self.path}: topic {name!r} has type {conn.msgtype!r}; "
                    f"{what} needs {' or '.join(msgtypes)}"
                )
            if not self._supported(conn):
                raise BagError(
                    f"{self.path}: topic {name!r}: type {conn.msgtype!r} is not defined in the bag"
                )
        if name not in self._cache:
            return name, [msg for _, _, msg in self._iterate(conns, name)]
        return name, self._cache[name]

    def preload(self, topics=None) -> BagReader:
        """Read several topics in one pass and keep their messages for the typed views.

        Each typed view otherwise reads the file once; in a compressed bag that means
        decompressing every chunk again (about 0.4 s per view for the Olin bag).
        The kept messages are released by :meth:`close`.

        Parameters
        ----------
        topics : iterable of str, or None
            Topics to keep; ``None`` means every topic whose type a typed view reads
            (LaserScan, Odometry, PoseStamped, TFMessage).

        Returns
        -------
        BagReader
            ``self``, for chaining.
        """
        typed = {LASER_SCAN, ODOMETRY, POSE_STAMPED, TF_MESSAGE}
        if topics is None:
            names = {c.topic for c in self._connections if c.msgtype in typed}
        else:
            names = {self._resolve(t) for t in ([topics] if isinstance(topics, str) else topics)}
        conns = [c for c in self._connections if c.topic in names and self._supported(c)]
        kept: dict[str, list] = {name: [] for name in {c.topic for c in conns}}
        for conn, _, msg in self._iterate(conns, "preload"):
            kept[conn.topic].append(msg)
        self._cache.update(kept)  # only after the whole pass succeeded
        return self

    # -- typed views --------------------------------------------------------------------
    def scans(self, topic: str) -> Scans:
        """All laser scans of ``topic`` as one :class:`Scans`.

        Raises
        ------
        BagError
            No scans on the topic, scans of different lengths, or scans whose
            angles, range limits or frame differ (the message says which scan).
        """
        name, msgs = self._read_all(topic, (LASER_SCAN,), "scans()")
        if not msgs:
            raise BagError(f"{self.path}: topic {name!r} holds no scans (0 LaserScan messages)")
        lengths = np.array([len(m.ranges) for m in msgs])
        if np.any(lengths != lengths[0]):
            k = int(np.flatnonzero(lengths != lengths[0])[0])
            raise BagError(
                f"{self.path}: scans on {name!r} have mismatched lengths: "
                f"scan 0 has {lengths[0]} ranges, "
                f"scan {k} has {lengths[k]} (lengths seen: {sorted(set(lengths.tolist()))})"
            )
        if lengths[0] == 0:
            raise BagError(f"{self.path}: scans on {name!r} have no beams (empty ranges)")
        geometry = np.array(
            [(m.angle_min, m.angle_increment, m.range_min, m.range_max) for m in msgs], dtype=float
        )
        for j, field in enumerate(("angle_min", "angle_increment", "range_min", "range_max")):
            differ = geometry[:, j] != geometry[0, j]
            if np.any(differ):
                k = int(np.flatnonzero(differ)[0])
                raise BagError(
                    f"{self.path}: scans on {name!r} disagree on {field}: "
                    f"scan 0 has {geometry[0, j]}, scan {k} has {geometry[k, j]}"
                )
        frames = {m.header.frame_id for m in msgs}
        if len(frames) > 1:
            raise BagError(
                f"{self.path}: scans on {name!r} come from several frames: {sorted(frames)}"
            )
        angle_min, increment, range_min, range_max = geometry[0]
        return Scans(
            stamps=_stamps(msgs),
            ranges=np.stack([np.asarray(m.ranges) for m in msgs]).astype(float),
            angles=angle_min + increment * np.arange(lengths[0]),
            range_min=range_min,
            range_max=range_max,
            frame_id=frames.pop(),
        )

    def _track(self, name, msgs, rows, frame_ids, child_ids, what) -> PoseTrack:
        if not msgs:
            raise BagError(f"{self.path}: topic {name!r} holds no {what} messages")
        for label, ids in (("frame_id", frame_ids), ("child_frame_id", child_ids)):
            if len(set(ids)) > 1:
                raise BagError(
                    f"{self.path}: {what} on {name!r} mixes several {label}s: {sorted(set(ids))}"
                )
        return PoseTrack(_stamps(msgs), _planar(rows), frame_ids[0], child_ids[0])

    def odometry(self, topic: str) -> PoseTrack:
        """``nav_msgs/Odometry`` of ``topic``: ``child_frame_id`` poses in ``header.frame_id``."""
        name, msgs = self._read_all(topic, (ODOMETRY,), "odometry()")
        rows = [_pose_row(m.pose.pose) for m in msgs]
        return self._track(
            name,
            msgs,
            rows,
            [m.header.frame_id for m in msgs],
            [m.child_frame_id for m in msgs],
            "odometry",
        )

    def poses(self, topic: str) -> PoseTrack:
        """``geometry_msgs/PoseStamped`` of ``topic`` (e.g. the Olin ``/map_pose`` ground truth).

        The returned track's ``child_frame_id`` is empty (a PoseStamped does not name it).
        """
        name, msgs = self._read_all(topic, (POSE_STAMPED,), "poses()")
        rows = [_pose_row(m.pose) for m in msgs]
        return self._track(
            name, msgs, rows, [m.header.frame_id for m in msgs], [""] * len(msgs), "PoseStamped"
        )

    def tf(self, topic: str = "/tf", static_topic: str | None = "/tf_static") -> TfTree:
        """Every TF edge of ``topic`` (and ``static_topic`` when the bag has it).

        Edges are keyed by frame ids without a leading slash. Each edge's track uses
        the transforms' own header stamps.

        Raises
        ------
        BagError
            Neither topic exists (the message lists the topics), or the file is corrupt.
        """
        sources, errors = [], []
        for t, is_static in ((topic, False), (static_topic, True)):
            if t is None:
                continue
            try:
                sources.append((self._resolve(t), is_static))
            except BagError as exc:
                errors.append(exc)
        if not sources:
            raise errors[0] if errors else ValueError("topic and static_topic cannot both be None")
        samples: dict[tuple[str, str], list] = {}
        dynamic: set[tuple[str, str]] = set()
        for name, is_static in sources:
            _, msgs = self._read_all(name, (TF_MESSAGE,), "tf()")
            for msg in msgs:
                for tr in msg.transforms:
                    key = (_frame(tr.header.frame_id), _frame(tr.child_frame_id))
                    v, q = tr.transform.translation, tr.transform.rotation
                    samples.setdefault(key, []).append(
                        (
                            tr.header.stamp.sec,
                            tr.header.stamp.nanosec,
                            v.x,
                            v.y,
                            v.z,
                            q.x,
                            q.y,
                            q.z,
                            q.w,
                        )
                    )
                    if not is_static:
                        dynamic.add(key)
        edges = {}
        for key, rows in samples.items():
            a = np.array(rows, dtype=float)
            stamps = a[:, 0] + a[:, 1] / 1e9
            edges[key] = PoseTrack(stamps, _planar(a[:, 2:]), key[0], key[1])
        return TfTree(edges, static=set(edges) - dynamic)


# ---------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------
def _split_stamp(stamp) -> tuple[int, int]:
    """Seconds -> (sec, nanosec), exact to the nanosecond for the float given."""
    try:
        t = float(stamp)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"stamp must be a number of seconds, got {type(stamp).__name__}") from exc
    if not math.isfinite(t) or t < 0:
        raise ValueError(f"stamp must be finite and >= 0 seconds, got {stamp!r}")
    sec = math.floor(t)
    nsec = round((t - sec) * 1e9)  # t - sec is exact, so no precision is lost at epoch times
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return int(sec), int(nsec)


def _ros1_typestore():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(_TF_MESSAGE_DEF, TF_MESSAGE))
    return store


class BagWriter:
    """Write a ROS1 bag (format v2.0) with scans, odometry, TF and poses.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; must end in ``.bag``. An existing file is **replaced**, but only
        when the writer closes successfully: messages go to a temporary file next to
        it, renamed over ``path`` by :meth:`close`. If an exception escapes the
        ``with`` block the temporary file is deleted and ``path`` is left untouched.
    overwrite : bool
        When False, an existing ``path`` raises FileExistsError.
    compression : {None, "lz4", "bz2"}
        Chunk compression, as ``rosbag record --lz4`` / ``--bz2`` write it. The file
        still starts with ``#ROSBAG V2.0``; readers decompress transparently.

    Notes
    -----
    Each message's record time in the bag is its stamp. Header ``seq`` counts up per
    topic. Write messages in time order (ROS tools expect it).

    Examples
    --------
    >>> with BagWriter(tmp / "run.bag") as bag:                          # doctest: +SKIP
    ...     bag.write_tf(0.0, [("base_link", "base_laser_link", (0.1, 0, 0))], topic="/tf_static")
    ...     bag.write_scan("/base_scan", 0.1, ranges, angle_min=-np.pi, angle_increment=np.pi / 180,
    ...                    range_min=0.02, range_max=5.0, frame_id="base_laser_link")
    """

    def __init__(self, path, *, overwrite: bool = True, compression: str | None = None):
        from rosbags.rosbag1 import Writer

        fmt = Writer.CompressionFormat
        formats = {None: None, "lz4": fmt.LZ4, "bz2": fmt.BZ2}
        if compression not in formats:
            raise ValueError(f"compression must be None, 'lz4' or 'bz2', got {compression!r}")

        self.path = Path(path)
        if self.path.suffix != ".bag":
            raise ValueError(f"path must end in .bag (a ROS1 bag), got {self.path}")
        if self.path.is_dir():
            raise IsADirectoryError(f"path is a directory, expected a .bag file: {self.path}")
        if self.path.exists() and not overwrite:
            raise FileExistsError(f"bag exists and overwrite=False: {self.path}")
        if not self.path.parent.is_dir():
            raise FileNotFoundError(f"folder for the bag does not exist: {self.path.parent}")
        self._tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        self._tmp.unlink(missing_ok=True)
        self._store = _ros1_typestore()
        self._types = self._store.types
        self._writer = Writer(self._tmp)
        if formats[compression] is not None:
            self._writer.set_compression(formats[compression])
        self._writer.open()
        self._connections: dict[str, tuple[object, str]] = {}
        self._seq: dict[str, int] = {}

    # -- lifecycle ----------------------------------------------------------------------
    def close(self) -> None:
        """Finish the bag (write its index) and move it to ``path``; idempotent."""
        writer, self._writer = self._writer, None
        if writer is None:
            return
        try:
            writer.close()
            os.replace(self._tmp, self.path)
        except BaseException:
            self._tmp.unlink(missing_ok=True)
            raise

    def abort(self) -> None:
        """Discard everything written; ``path`` is left as it was."""
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.abort()
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # -- plumbing -------------------------------------------------------------------------
    def _write(self, topic: str, msgtype: str, stamp: float, msg) -> None:
        if self._writer is None:
            raise ValueError(f"{self.path}: the bag writer is closed")
        if not isinstance(topic, str) or not topic:
            raise ValueError(f"topic must be a non-empty str, got {topic!r}")
        if topic not in self._connections:
            latching = 1 if topic == "/tf_static" else None
            conn = self._writer.add_connection(
                topic, msgtype, typestore=self._store, latching=latching
            )
            self._connections[topic] = (conn, msgtype)
        conn, known = self._connections[topic]
        if known != msgtype:
            raise ValueError(
                f"topic {topic!r} already carries {known}, cannot write a {msgtype} to it"
            )
        sec, nsec = _split_stamp(stamp)
        self._writer.write(
            conn, sec * 1_000_000_000 + nsec, self._store.serialize_ros1(msg, msgtype)
        )

    def _header(self, topic: str, stamp: float, frame_id: str):
        if not isinstance(frame_id, str):
            raise TypeError(f"frame_id must be a str, got {type(frame_id).__name__}")
        seq = self._seq.get(topic, 0)
        self._seq[topic] = seq + 1
        sec, nsec = _split_stamp(stamp)
        return self._types["std_msgs/msg/Header"](
            seq=seq,
            stamp=self._types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
            frame_id=frame_id,
        )

    def _pose(self, name: str, pose):
        x, y, theta = as_array(name, pose, shape=(3,), finite=True)
        qx, qy, qz, qw = quaternion_from_yaw(theta)
        t = self._types
        return (
            t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
            t["geometry_msgs/msg/Quaternion"](x=float(qx), y=float(qy), z=float(qz), w=float(qw)),
        )

    # -- messages ---------------------------------------------------------------------------
    def write_scan(
        self,
        topic: str,
        stamp: float,
        ranges,
        *,
        angle_min: float,
        angle_increment: float,
        range_min: float,
        range_max: float,
        frame_id: str,
        scan_time: float = 0.0,
        time_increment: float = 0.0,
    ) -> None:
        """Write one ``sensor_msgs/LaserScan``.

        ``ranges`` (B,) in metres are stored as float32, as in ROS; inf, NaN and 0
        are written as given (no-return conventions differ between drivers).
        ``angle_max`` is ``angle_min + (B - 1) * angle_increment``.
        """
        r = as_array("ranges", ranges, ndim=1).astype(np.float32)
        if r.size == 0:
            raise ValueError("ranges must hold at least one beam")
        values = {
            "angle_min": angle_min,
            "angle_increment": angle_increment,
            "range_min": range_min,
            "range_max": range_max,
            "scan_time": scan_time,
            "time_increment": time_increment,
        }
        for k, v in values.items():
            values[k] = float(as_array(k, v, ndim=0, finite=True))
        if not 0 <= values["range_min"] < values["range_max"]:
            raise ValueError(
                f"range_min and range_max must satisfy 0 <= range_min < range_max, "
                f"got {range_min}, {range_max}"
            )
        msg = self._types[LASER_SCAN](
            header=self._header(topic, stamp, frame_id),
            angle_max=values["angle_min"] + (r.size - 1) * values["angle_increment"],
            ranges=r,
            intensities=np.zeros(0, dtype=np.float32),
            **values,
        )
        self._write(topic, LASER_SCAN, stamp, msg)

    def write_odometry(
        self,
        topic: str,
        stamp: float,
        pose,
        *,
        frame_id: str,
        child_frame_id: str,
        twist=(0.0, 0.0),
    ) -> None:
        """Write one ``nav_msgs/Odometry``: ``pose`` of ``child_frame_id`` in ``frame_id``.

        ``twist`` is ``(v, w)``: forward speed (m/s) and turn rate (rad/s) in the child frame.
        Covariances are zero.
        """
        if not isinstance(child_frame_id, str):
            raise TypeError(f"child_frame_id must be a str, got {type(child_frame_id).__name__}")
        v, w = as_array("twist", twist, shape=(2,), finite=True)
        t = self._types
        point, quat = self._pose("pose", pose)
        vec = t["geometry_msgs/msg/Vector3"]
        msg = t[ODOMETRY](
            header=self._header(topic, stamp, frame_id),
            child_frame_id=child_frame_id,
            pose=t["geometry_msgs/msg/PoseWithCovariance"](
                pose=t["geometry_msgs/msg/Pose"](position=point, orientation=quat),
                covariance=np.zeros(36),
            ),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](
                    linear=vec(x=float(v), y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=float(w))
                ),
                covariance=np.zeros(36),
            ),
        )
        self._write(topic, ODOMETRY, stamp, msg)

    def write_tf(self, stamp: float, transforms, *, topic: str = "/tf") -> None:
        """Write one ``tf2_msgs/TFMessage`` holding ``transforms``.

        Parameters
        ----------
        stamp : float
            Seconds; every transform gets this header stamp.
        transforms : iterable of (parent, child, pose)
            ``pose`` (x, y, theta) of ``child`` in ``parent``.
        topic : str
            ``"/tf"``, or ``"/tf_static"`` for transforms that hold at all times
            (written latched, as ROS does).
        """
        t = self._types
        items = []
        for k, item in enumerate(transforms):
            try:
                parent, child, pose = item
            except (TypeError, ValueError) as exc:
                raise ValueError(
                    f"transforms[{k}] must be (parent, child, pose), got {item!r}"
                ) from exc
            if not (isinstance(parent, str) and isinstance(child, str) and parent and child):
                raise ValueError(
                    f"transforms[{k}] frames must be non-empty strings, got {parent!r}, {child!r}"
                )
            point, quat = self._pose(f"transforms[{k}] pose", pose)
            items.append(
                t["geometry_msgs/msg/TransformStamped"](
                    header=self._header(f"{topic} {parent}->{child}", stamp, parent),
                    child_frame_id=child,
                    transform=t["geometry_msgs/msg/Transform"](
                        translation=t["geometry_msgs/msg/Vector3"](x=point.x, y=point.y, z=0.0),
                        rotation=quat,
                    ),
                )
            )
        if not items:
            raise ValueError("transforms must hold at least one (parent, child, pose)")
        self._write(topic, TF_MESSAGE, stamp, t[TF_MESSAGE](transforms=items))

    def write_pose_stamped(self, topic: str, stamp: float, pose, *, frame_id: str) -> None:
        """Write one ``geometry_msgs/PoseStamped``: ``pose`` (x, y, theta) in ``frame_id``."""
        point, quat = self._pose("pose", pose)
        t = self._types
        msg = t[POSE_STAMPED](
            header=self._header(topic, stamp, frame_id),
            pose=t["geometry_msgs/msg/Pose"](position=point, orientation=quat),
        )
        self._write(topic, POSE_STAMPED, stamp, msg)
