"""Lab 07 on real data: FastSLAM 1.0 on the Freiburg course's data set and on UTIAS MRCLAM.

MRCLAM (:func:`run_fastslam_mrclam`) gives unicycle commands on a 0.02 s grid, as the
lab's fiducial robot does. Freiburg (:func:`run_fastslam_freiburg`):

The data set's motion is the odometry motion model ``(r1, t, r2)``; the lab's
:func:`fastslam_step` takes unicycle commands ``(v, w)`` with an Euler step
``x += v dt cos(theta)``, ``theta += w dt``. One odometry step is exactly two such
steps with ``dt = 1``: ``(0, r1)`` turns by ``r1``, then ``(t, r2)`` drives ``t`` along
the new heading and turns by ``r2``. The observations go with the second.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robolab.datasets.freiburg import FreiburgData
from robolab.datasets.mrclam import MrclamRun
from robolab.evaluation import align_points
from robolab.geometry import transform_points
from robolab.validation import check_count, check_rng

__all__ = ["MOTION_NOISE", "MEASUREMENT_NOISE", "run_fastslam_freiburg", "run_fastslam_mrclam"]

#: Standard deviations of the odometry ``(r1, t, r2)``: radians, metres, radians
#: (the course's FastSLAM exercise).
MOTION_NOISE = (0.005, 0.01, 0.005)
#: The measurement noise covariance ``Qt`` of range (m^2) and bearing (rad^2) of the course.
MEASUREMENT_NOISE = np.diag([0.1, 0.1])


def run_fastslam_freiburg(
    data: FreiburgData,
    n_particles: int,
    rng: np.random.Generator,
    *,
    fastslam_step: Callable,
    init_particles: Callable,
    ess_threshold: float | None = 0.5,
    motion_noise=MOTION_NOISE,
    Qt=MEASUREMENT_NOISE,
) -> dict:
    """Run the lab's FastSLAM functions over a Freiburg data set.

    Parameters
    ----------
    data : FreiburgData
        From :func:`robolab.datasets.read_freiburg`.
    n_particles : int
    rng : numpy.random.Generator
    fastslam_step, init_particles : callable
        The lab's functions, as the notebook defines them (the library never
        imports the reference solutions: the student edition has none).
    ess_threshold : float or None
        Resample when the effective sample size falls below ``ess_threshold * M``
        (default 0.5), passed as ``fastslam_step``'s ``resample``; None resamples
        after every step with an observation (the book, ``resample=True``).
    motion_noise : (sigma_r1, sigma_t, sigma_r2)
    Qt : array_like, shape (2, 2)

    Returns
    -------
    dict
        ``path`` (T + 1, 3) weighted-mean poses, ``landmarks`` (K, 2) weighted-mean
        landmark estimates in the rows of ``data.landmarks`` (NaN if never seen),
        ``rmse`` against ``data.landmarks`` as estimated (the frame is fixed by the
        start at the origin) and ``rmse_aligned`` after SE(2) alignment, ``alignment``
        (3,), ``resamples`` (how many steps resampled), ``state`` the final particles.
    """
    if not (callable(fastslam_step) and callable(init_particles)):
        raise TypeError("fastslam_step and init_particles must be the lab's functions (callables)")
    n = check_count("n_particles", n_particles)
    check_rng(rng)
    s_r1, s_t, s_r2 = (float(v) for v in motion_noise)
    q_turn = np.diag([0.0, 0.0, s_r1**2])
    q_drive = np.diag([s_t**2, s_t**2, s_r2**2])
    k = len(data.landmark_ids)
    state = init_particles(n, k, np.zeros(3), "first_observation")
    resample = True if ess_threshold is None else float(ess_threshold)
    path, resamples, seen = [_mean_pose(state)], 0, np.zeros(k, dtype=bool)
    for i, (r1, t, r2) in enumerate(data.odometry):
        state = fastslam_step(state, [0.0, r1], None, q_turn, Qt, rng, 1.0)
        obs = data.indexed_observations(i)
        state = fastslam_step(state, [t, r2], obs, q_drive, Qt, rng, 1.0, resample)
        resamples += _resampled(state, obs, seen, resample)
        path.append(_mean_pose(state))
    return _scored(state, seen, data.landmarks, path, resamples)


def run_fastslam_mrclam(
    run: MrclamRun,
    n_particles: int,
    rng: np.random.Generator,
    *,
    fastslam_step: Callable,
    init_particles: Callable,
    Q,
    Qt,
    ess_threshold: float | None = 0.5,
    steps: int | None = None,
) -> dict:
    """Run the lab's FastSLAM functions over one robot of an MRCLAM data set.

    The robot starts at its true first pose (which fixes the map's frame); step ``s``
    drives with the command in force at ``run.t[s - 1]`` for ``run.dt`` seconds, then
    weighs the landmark measurements of step ``s`` (``run.observations(s)``, rows
    ``[range, bearing, landmark row]``).

    Parameters
    ----------
    run : MrclamRun
        From :func:`robolab.datasets.read_mrclam`.
    n_particles : int
    rng : numpy.random.Generator
    fastslam_step, init_particles : callable
        The lab's functions, as the notebook defines them.
    Q : array_like, shape (3, 3)
        Motion noise covariance per step; ``Qt`` (2, 2) the measurement noise's.
    ess_threshold : float or None
        As in :func:`run_fastslam_freiburg`.
    steps : int, optional
        Only the first ``steps`` steps (default: the whole run).

    Returns
    -------
    dict
        As :func:`run_fastslam_freiburg`, plus ``path_error`` (S,) metres against
        ``run.truth``.
    """
    if not (callable(fastslam_step) and callable(init_particles)):
        raise TypeError("fastslam_step and init_particles must be the lab's functions (callables)")
    n = check_count("n_particles", n_particles)
    check_rng(rng)
    last = len(run) if steps is None else min(len(run), check_count("steps", steps))
    k = len(run.landmarks)
    state = init_particles(n, k, np.asarray(run.truth[0], dtype=float), "first_observation")
    resample = True if ess_threshold is None else float(ess_threshold)
    path, resamples, seen = [_mean_pose(state)], 0, np.zeros(k, dtype=bool)
    for s in range(1, last):
        obs = run.observations(s)
        state = fastslam_step(state, run.commands[s - 1], obs, Q, Qt, rng, run.dt, resample)
        resamples += _resampled(state, obs, seen, resample)
        path.append(_mean_pose(state))
    result = _scored(state, seen, run.landmarks, path, resamples)
    truth = run.truth[:last]
    result["path_error"] = np.hypot(*(result["path"][:, :2] - truth[:, :2]).T)
    return result


def _resampled(state, obs, seen, resample) -> bool:
    """Whether the step that saw ``obs`` resampled; marks the landmarks it saw in ``seen``.

    Equal weights after the step mean it resampled, unless every landmark it saw was new:
    first sightings weigh all particles alike, so under an ESS threshold nothing was
    resampled (step 0 is such a step).
    """
    if obs is None or not len(obs):
        return False
    ids = np.asarray(obs)[:, 2].astype(np.intp)
    informative = resample is True or bool(seen[ids].any())
    seen[ids] = True
    return informative and bool(np.all(state["weights"] == state["weights"][0]))


def _scored(state, seen, true_landmarks, path, resamples) -> dict:
    """The weighted-mean map of ``state`` against the true landmarks (unseen ones NaN)."""
    w = np.asarray(state["weights"])
    landmarks = np.einsum("k,kjd->jd", w, np.asarray(state["means"]))
    landmarks[~seen] = np.nan
    err = np.hypot(*(landmarks - true_landmarks).T)
    try:
        pose = align_points(landmarks, true_landmarks)  # NaN rows (unseen) are left out
        aligned = np.hypot(*(transform_points(landmarks, pose) - true_landmarks).T)
    except ValueError:  # fewer than two distinct landmarks fix no rotation: no alignment
        pose, aligned = np.zeros(3), err
    return {
        "path": np.array(path),
        "landmarks": landmarks,
        "rmse": float(np.sqrt(np.nanmean(err**2))),
        "rmse_aligned": float(np.sqrt(np.nanmean(aligned**2))),
        "alignment": pose,
        "resamples": int(resamples),
        "state": state,
    }


def _mean_pose(state) -> np.ndarray:
    w, p = np.asarray(state["weights"]), np.asarray(state["poses"])
    return np.array(
        [w @ p[:, 0], w @ p[:, 1], np.arctan2(w @ np.sin(p[:, 2]), w @ np.cos(p[:, 2]))]
    )
