"""Writing ROS1 bags (format v2.0)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from robolab.bag.messages import _TF_MESSAGE_DEF, LASER_SCAN, ODOMETRY, POSE_STAMPED, TF_MESSAGE
from robolab.geometry import (
    quaternion_from_yaw,
)
from robolab.validation import as_array


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
