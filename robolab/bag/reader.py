"""Reading ROS1 and ROS2 bags into typed views."""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from robolab.bag.messages import (
    LASER_SCAN,
    ODOMETRY,
    POSE_STAMPED,
    TF_MESSAGE,
    BagError,
    TopicInfo,
    _planar,
    _pose_row,
    _stamps,
)
from robolab.bag.poses import PoseTrack
from robolab.bag.scans import Scans
from robolab.bag.tf import TfTree, _frame

#: The first line of every ROS1 bag file.
ROS1_MAGIC = b"#ROSBAG V2.0\n"


def _check_ros2_folder(path: Path) -> None:
    """BagError naming what is missing when folder ``path`` is not a ROS2 bag."""
    if (path / "metadata.yaml").is_file():
        return
    inside = sorted(p.name for p in path.iterdir())
    if not inside:
        raise BagError(f"{path}: is an empty folder, not a ROS2 bag (no metadata.yaml)")
    storage = [n for n in inside if n.endswith((".db3", ".mcap"))]
    hint = (
        f"; it holds {', '.join(storage[:3])} (`ros2 bag reindex` rebuilds the metadata)"
        if storage
        else f"; it holds {len(inside)} other file(s) and no .db3 or .mcap"
    )
    raise BagError(f"{path}: is a folder but not a ROS2 bag: it has no metadata.yaml{hint}")


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
        If the file is not a readable bag (truncated, corrupt header, unknown format),
        or a folder is not a ROS2 bag (empty, or without its ``metadata.yaml``).

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
        if self.path.is_dir():
            _check_ros2_folder(self.path)
        from robolab.bag.ros1 import LatestTypestore, any_reader_class

        self._reader = None
        with self._wrap("cannot open bag"):
            # AnyReader, or a ROS1-only reader where rosbags' ROS2 reader cannot be imported
            reader = any_reader_class()([self.path], default_typestore=LatestTypestore())
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
            if self.path.is_file():
                with open(self.path, "rb") as fh:
                    ros1 = fh.read(13) == ROS1_MAGIC
                if ros1 and self.path.suffix != ".bag":
                    hint = " (this is a ROS1 bag: its name must end in .bag)"
                elif not ros1 and self.path.suffix == ".bag":
                    hint = f" (not a ROS1 bag: it does not start with {ROS1_MAGIC!r})"
            text = " ".join(str(exc).split())  # one line, whatever the parser printed
            raise BagError(f"{self.path}: {what}: {type(exc).__name__}: {text}{hint}") from exc

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
                from robolab.progress import progress_bar

                label = f"{self.path.name}: {desc}"
                stream = progress_bar(stream, total=total, desc=label, unit="msg")
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
