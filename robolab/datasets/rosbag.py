"""ROS bags with configurable topics and message types: scans, odometry and ground truth.

A *pose source* names where a track of poses comes from:

* a topic name (``"/odom"``, ``"/map_pose"``): its message type, read from the bag,
  decides how: ``nav_msgs/Odometry`` or ``geometry_msgs/PoseStamped``;
* ``("/tf", parent, child)``: the TF transform ``parent -> child``, chained over
  several edges if needed, sampled at the stamps of the edges it chains.

So the simulated bags (``/base_scan``, Odometry ``/ground_truth``) and a real Neato
bag (``/scan``, PoseStamped ``/map_pose``) load with the same function.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robolab.bag import (
    ODOMETRY,
    POSE_STAMPED,
    TF_MESSAGE,
    BagError,
    BagReader,
    PoseTrack,
    Scans,
    laser_pose_in_base,
)

__all__ = ["Recording", "read_track", "read_recording"]


def read_track(bag: BagReader, source) -> PoseTrack:
    """The poses of ``source`` (see the module docstring) as a :class:`robolab.bag.PoseTrack`.

    Raises
    ------
    BagError
        No such topic, a topic of another message type, or TF frames that are not connected.
    TypeError
        ``source`` is neither a topic name nor a ``(tf_topic, parent, child)`` tuple.
    """
    if isinstance(source, str):
        name = bag._resolve(source)  # noqa: SLF001 - the reader's topic lookup
        msgtype = bag.topics[name].msgtype
        if msgtype == ODOMETRY:
            return bag.odometry(name)
        if msgtype == POSE_STAMPED:
            return bag.poses(name)
        raise BagError(
            f"{bag.path}: topic {name!r} has type {msgtype!r}; a pose source is an Odometry or "
            f"PoseStamped topic, or (tf_topic, parent, child) for a {TF_MESSAGE} transform"
        )
    if isinstance(source, tuple) and len(source) == 3 and all(isinstance(s, str) for s in source):
        topic, parent, child = source
        tf = bag.tf(topic)
        chain = tf.chain(parent, child)
        moving = [tf.edges[key] for key, _ in chain if key not in tf.static]
        if not moving:  # a rigid transform: one sample
            return PoseTrack(np.zeros(1), tf.lookup(parent, child)[None], parent, child)
        lo = max(track.stamps.min() for track in moving)
        hi = min(track.stamps.max() for track in moving)
        stamps = np.unique(np.concatenate([track.stamps for track in moving]))
        stamps = stamps[(stamps >= lo) & (stamps <= hi)]
        if stamps.size == 0:
            raise BagError(f"{bag.path}: the TF edges from {parent!r} to {child!r} never overlap")
        return PoseTrack(stamps, tf.lookup(parent, child, stamps), parent, child)
    raise TypeError(
        f"a pose source is a topic name or a (tf_topic, parent, child) tuple, got {source!r}"
    )


@dataclass(frozen=True, eq=False)
class Recording:
    """Scans with odometry and ground truth at the scan stamps.

    Attributes
    ----------
    scans : robolab.bag.Scans
        The scans inside the time span that odometry and truth both cover.
    odom : numpy.ndarray, shape (T, 3)
        Odometry interpolated at each scan stamp.
    truth : numpy.ndarray, shape (T, 3), or None
        Ground truth interpolated at each scan stamp (None without a truth source).
    laser_pose : numpy.ndarray, shape (3,)
        The laser in the base frame.
    """

    scans: Scans
    odom: np.ndarray
    truth: np.ndarray | None
    laser_pose: np.ndarray

    def __len__(self) -> int:
        return len(self.scans)


def read_recording(
    path,
    *,
    scan_topic: str = "/base_scan",
    odom="/odom",
    truth="/ground_truth",
    base_frame: str = "base_link",
    tf_topic: str = "/tf",
    truth_delay: float = 0.0,
    scan_delay: float = 0.0,
) -> Recording:
    """Read scans, odometry and ground truth from a bag, each from a configurable source.

    Parameters
    ----------
    path : str or Path
        The bag.
    scan_topic : str
        A ``sensor_msgs/LaserScan`` topic (``"/base_scan"`` in the simulated bags,
        ``"/scan"`` in the Olin Neato bag).
    odom, truth : pose source
        A topic (Odometry or PoseStamped) or ``(tf_topic, parent, child)``; ``truth``
        may be None.
    base_frame : str
        The robot's frame: the laser mount is ``base_frame -> scans.frame_id`` on TF.
    tf_topic : str
        Where the laser mount is read.
    truth_delay : float
        Seconds by which the truth's stamps run late against odometry: the truth of a
        scan is read at ``stamp + truth_delay`` (a positive value: the camera's clock
        is late).
    scan_delay : float
        Seconds by which the scans' stamps run late against odometry and truth: a scan
        stamped ``s`` was taken at ``s - scan_delay``, so odometry and truth are read
        there. On the Olin Neato recordings it is the scans that are late, by about
        0.3 s (measured on three recordings: MCL's scan-based estimates agree best with
        odometry and camera truth read 0.3 s before the scan stamps), so pass
        ``scan_delay=0.3`` there; ``truth_delay`` stays 0.

    Returns
    -------
    Recording
    """
    with BagReader(Path(path)) as bag:
        bag.preload()
        scans = bag.scans(scan_topic)
        odom_track = read_track(bag, odom)
        truth_track = None if truth is None else read_track(bag, truth)
        laser = laser_pose_in_base(bag.tf(tf_topic), scans.frame_id, base_frame)
    delay, late = float(truth_delay), float(scan_delay)
    if not (np.isfinite(delay) and np.isfinite(late)):
        raise ValueError(f"truth_delay and scan_delay must be finite seconds, got {delay}, {late}")
    # every time below is the scans' clock: odometry and truth are read at stamp - late
    lo, hi = odom_track.stamps.min() + late, odom_track.stamps.max() + late
    if truth_track is not None:
        lo = max(lo, truth_track.stamps.min() - delay + late)
        hi = min(hi, truth_track.stamps.max() - delay + late)
    keep = (scans.stamps >= lo) & (scans.stamps <= hi)
    if not keep.any():
        raise BagError(f"{path}: no scan lies in the time span of odometry and ground truth")
    kept = Scans(
        scans.stamps[keep],
        scans.ranges[keep],
        scans.angles,
        scans.range_min,
        scans.range_max,
        scans.frame_id,
    )
    return Recording(
        scans=kept,
        odom=odom_track.at(kept.stamps - late),
        truth=None if truth_track is None else truth_track.at(kept.stamps - late + delay),
        laser_pose=np.asarray(laser, dtype=float),
    )
