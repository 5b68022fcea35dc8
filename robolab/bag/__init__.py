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

Modules
-------
``messages`` (type names, :class:`BagError`, :class:`TopicInfo`), ``scans``
(:class:`Scans`), ``poses`` (:class:`PoseTrack`), ``tf`` (:class:`TfTree`,
:func:`laser_pose_in_base`), ``reader`` (:class:`BagReader`), ``writer``
(:class:`BagWriter`). Import from ``robolab.bag``.
"""

from robolab.bag.messages import (
    LASER_SCAN,
    ODOMETRY,
    POSE_STAMPED,
    TF_MESSAGE,
    BagError,
    TopicInfo,
)
from robolab.bag.poses import PoseTrack
from robolab.bag.reader import BagReader
from robolab.bag.scans import Scans
from robolab.bag.tf import TfTree, laser_pose_in_base
from robolab.bag.writer import BagWriter

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
