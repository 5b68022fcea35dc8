"""Storing a simulated run as a ROS1 bag."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from robolab.sim.run import SimRun
from robolab.validation import check_positive

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
      ``/tf`` and the scans, like AMCL's processBag, has the laser frame);
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
