"""The heading of the path is the arithmetic mean of the particles' headings, not the circular
mean.

Which estimate is reported (the heading of the path; circular mean).

class: reported-estimate
"""

import numpy as np

from robolab.fiducials import as_robot
from robolab.validation import check_rng
from solutions.fastslam import _mean_pose, fastslam_step, init_particles


def fastslam(
    robot_or_run, n_particles, rng, init="first_observation", Q=None, Qt=None, history=False
):
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
        path.append(state["weights"] @ state["poses"])
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
