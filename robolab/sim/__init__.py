"""The simulator behind the bundled data, and ``robolab data``.

A differential-drive robot follows a route of waypoints through an occupancy
grid. The simulator records

- the **ground truth** pose ``map -> base_link``;
- **wheel odometry** ``odom -> base_link`` that drifts like a real robot's:
  every odometry step perturbs the true relative motion ``(rot1, trans, rot2)``
  with the noise of the odometry motion model (Probabilistic Robotics,
  Table 5.6, run "in reverse": the robot moves along the true path and the
  *reported* motion is the noisy one) and a small systematic bias from
  wheel-radius and wheel-base calibration errors, so that a map built from raw
  odometry smears (lab 04);
- **laser scans** ray cast from the laser's true pose ``base_link ->
  base_laser_link`` with the noise of the beam model (Table 6.1): Gaussian hit
  noise, short readings, max-range failures and random readings.

:func:`write_bag` stores a run as a ROS1 bag, :func:`make_data` regenerates
every file in ``data/`` from fixed seeds (see ``data/README.md``).

Time: a run's stamps ``t`` are seconds since the start of the run; the bag
stamps are ``start_time + t`` (ROS time, seconds since the epoch).

Modules
-------
``laser`` (:class:`LaserModel`, :func:`scan_noise`), ``odometry``
(:class:`OdometryNoise`, :func:`odometry_from_truth`), ``motion`` (:class:`Controller`,
:func:`follow_route`), ``run`` (:class:`SimRun`, :func:`simulate`), ``bagfile``
(:func:`write_bag`), ``runs`` (the bundled routes and runs), ``ekf`` (:func:`ekf_world`),
``make`` (:func:`make_data`). Import from ``robolab.sim``.
"""

from robolab.sim.bagfile import BAG_TOPICS, write_bag
from robolab.sim.ekf import ekf_world
from robolab.sim.laser import LaserModel, scan_noise
from robolab.sim.make import DATASETS, make_data
from robolab.sim.motion import Controller, follow_route
from robolab.sim.odometry import OdometryNoise, odometry_from_truth
from robolab.sim.run import START_TIME, SimRun, clearance_field, simulate
from robolab.sim.runs import (
    LOCALIZATION_DURATION,  # noqa: F401 (public constant)
    LOCALIZATION_ROUTE,
    LOCALIZATION_START,
    MAPPING_DURATION,  # noqa: F401 (public constant)
    MAPPING_ROUTE,
    MAPPING_START,
    SEEDS,  # noqa: F401 (public constant)
    localization_run,
    mapping_run,
)

__all__ = [
    "LaserModel",
    "OdometryNoise",
    "Controller",
    "SimRun",
    "follow_route",
    "simulate",
    "write_bag",
    "odometry_from_truth",
    "scan_noise",
    "clearance_field",
    "mapping_run",
    "localization_run",
    "ekf_world",
    "make_data",
    "DATASETS",
    "START_TIME",
    "BAG_TOPICS",
    "MAPPING_ROUTE",
    "MAPPING_START",
    "LOCALIZATION_ROUTE",
    "LOCALIZATION_START",
]
