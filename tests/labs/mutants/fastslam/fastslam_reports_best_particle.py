"""The path reports the heaviest particle (after resampling: particle 0) instead of the mean.

Which estimate is reported.

class: reported-estimate
"""

import numpy as np

from robolab.fiducials import as_robot
from robolab.validation import check_rng
from solutions.fastslam import _mean_pose, fastslam_step, init_particles


def fastslam(
    robot_or_run, n_particles, rng, init="first_observation", Q=None, Qt=None, history=False
):
    r"""Run FastSLAM 1.0 over a whole run of the fiducial robot (seed 003's main loop).

    ::

        state = init_particles(M, K, x0, init)
        while robot.run():
            state = fastslam_step(state, robot.input(), robot.measurement(), Q, Qt, rng)

    Estimates reported (document of choice): the pose estimate at each step is
    the mean of the particles after the step (after resampling all weights are
    equal; the heading is the circular mean). The final map is the weighted
    mixture of the particles' landmark Gaussians, moment-matched:
    :math:`\bar\mu_j = \sum_k w_k \mu_{k,j}`,
    :math:`\bar\Sigma_j = \sum_k w_k (\Sigma_{k,j} + (\mu_{k,j}-\bar\mu_j)(\mu_{k,j}-\bar\mu_j)^T)`.
    Landmarks never observed are reported as NaN.

    Parameters
    ----------
    robot_or_run : FiducialRobot, FiducialRun or path
        A :class:`robolab.fiducials.FiducialRobot` (driven from its current
        step), or a recorded :class:`robolab.fiducials.FiducialRun` / ``.npz``
        path (replayed from its start).
    n_particles : int
        Number of particles M.
    rng : numpy.random.Generator
    init : {"first_observation", "prior"}
        Landmark initialization (:func:`init_particles`). The default is the
        book's: the seed's ``"prior"`` linearizes the first update of every
        landmark at the origin, which can leave it metres off with a small
        covariance for hundreds of steps (the notebook shows it).
    Q, Qt : array_like, optional
        Noise covariances the filter assumes; default the robot's own.
    history : bool
        Also return every particle's pose at every step.

    Returns
    -------
    dict
        ``path`` (T+1, 3) estimated poses (row 0 is ``x0``); ``landmarks`` (K, 2);
        ``landmark_covs`` (K, 2, 2); ``observed`` (K,) bool; ``state`` the final
        particle set; with ``history=True`` also ``particles`` (T+1, M, 3).
    """
    robot = as_robot(robot_or_run)
    check_rng(rng)
    q = robot.Q if Q is None else Q
    qt = robot.Qt if Qt is None else Qt
    state = init_particles(n_particles, robot.n_fiducials, robot.x0, init)
    path = [_mean_pose(state["poses"], state["weights"])]
    particles = [state["poses"]] if history else None
    observed = np.zeros(robot.n_fiducials, dtype=bool)
    while robot.run():
        z = robot.measurement()
        observed[z[:, 2].astype(np.intp)] = True
        state = fastslam_step(state, robot.input(), z, q, qt, rng, dt=robot.dt)
        path.append(state["poses"][np.argmax(state["weights"])].copy())
        if history:
            particles.append(state["poses"])
    w = state["weights"]
    lm = np.einsum("k,kjd->jd", w, state["means"])
    d = state["means"] - lm
    lm_cov = np.einsum("k,kjab->jab", w, state["covs"]) + np.einsum("k,kja,kjb->jab", w, d, d)
    lm[~observed] = np.nan
    lm_cov[~observed] = np.nan
    out = {
        "path": np.array(path),
        "landmarks": lm,
        "landmark_covs": lm_cov,
        "observed": observed,
        "state": state,
    }
    if history:
        out["particles"] = np.array(particles)
    return out
