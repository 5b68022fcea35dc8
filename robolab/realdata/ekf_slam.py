"""Lab 08 on real data: EKF-SLAM on the Freiburg course's range-bearing data set.

The data set's motion is the odometry motion model ``(r1, t, r2)``: the lab's
``ekf_slam`` runs it with ``predict(..., motion="odometry")`` when it is given a
:class:`robolab.datasets.FreiburgData`. The data has no ground-truth path and no
noise model; the map is scored against ``world.dat`` after an SE(2) alignment
(the filter's frame is the start pose, the file's is its own).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robolab.datasets.freiburg import FreiburgData
from robolab.evaluation import align_points
from robolab.geometry import transform_points

__all__ = ["MOTION_NOISE", "MEASUREMENT_NOISE", "run_ekf_slam_freiburg"]

#: Motion noise covariance R in the pose's coordinates (m^2, m^2, rad^2) per odometry step: lab
#: 07's odometry noise on this data (0.01 m of translation, two turns of 0.005 rad each) as
#: additive pose noise. The data carries no noise model of its own.
MOTION_NOISE = np.diag([0.01**2, 0.01**2, 2 * 0.005**2])
#: Measurement noise covariance Qt of range (m^2) and bearing (rad^2), as lab 07's.
MEASUREMENT_NOISE = np.diag([0.1, 0.1])


def run_ekf_slam_freiburg(
    data: FreiburgData,
    ekf_slam: Callable,
    *,
    R=MOTION_NOISE,
    Qt=MEASUREMENT_NOISE,
    history: bool = False,
) -> dict:
    """Run the lab's ``ekf_slam`` over a Freiburg data set and score the map.

    Parameters
    ----------
    data : FreiburgData
        From :func:`robolab.datasets.read_freiburg`.
    ekf_slam : callable
        The lab's ``ekf_slam(run, R, Qt, history)``, as the notebook defines it (the
        library never imports the reference solutions: the student edition has none).
    R, Qt : array_like
        Noise covariances (:data:`MOTION_NOISE`, :data:`MEASUREMENT_NOISE`).
    history : bool
        Passed on (means and covariances after every step).

    Returns
    -------
    dict
        What ``ekf_slam`` returns, plus ``rmse`` (landmarks against ``world.dat`` as
        estimated), ``rmse_aligned`` (after the best SE(2) alignment) and ``alignment``
        (3,), the pose that maps the estimate onto ``world.dat``.
    """
    if not isinstance(data, FreiburgData):
        raise TypeError(f"data must be a FreiburgData (read_freiburg), got {type(data).__name__}")
    if not callable(ekf_slam):
        raise TypeError(f"ekf_slam must be the lab's function, got {type(ekf_slam).__name__}")
    out = dict(ekf_slam(data, R=R, Qt=Qt, history=history))
    landmarks = np.asarray(out["landmarks"], dtype=float)
    err = np.hypot(*(landmarks - data.landmarks).T)
    pose = align_points(landmarks, data.landmarks)
    aligned = np.hypot(*(transform_points(landmarks, pose) - data.landmarks).T)
    out.update(
        rmse=float(np.sqrt(np.nanmean(err**2))),
        rmse_aligned=float(np.sqrt(np.nanmean(aligned**2))),
        alignment=pose,
    )
    return out
