"""Message type names, errors and conversions of message fields shared by reading and writing."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robolab.geometry import (
    yaw_from_quaternion,
)

#: Message type names as ``rosbags`` spells them (ROS1 types get the ``/msg/`` part too).
LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"

# Noetic's tf2_msgs/TFMessage; rosbags' ROS1 store lacks it. md5 94810edda583a504dfda3829e70d7eec.
_TF_MESSAGE_DEF = "geometry_msgs/TransformStamped[] transforms"


class BagError(ValueError):
    """A bag cannot be read as asked: corrupt or truncated file, missing topic, bad content."""


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
