"""A simulated pose-landmark graph for lab 09 (``robolab data`` writes ``data/graph_slam.g2o``).

A robot drives laps of a rectangular block (a corridor loop) through a field of
landmarks. Every step adds an odometry edge (the true relative motion plus Gaussian
noise); when the robot comes back within ``loop_radius`` of a pose of an earlier lap,
a loop-closure edge (as a scan matcher would give) joins the two; every landmark
within ``sensor_range`` adds a pose-landmark edge (its position in the robot's frame
plus noise). The initial guess composes the noisy odometry, so it drifts, and places
each landmark from its first sighting. Edge information matrices are the inverses
of the noise covariances actually used, so the optimum is a maximum-likelihood fit.
"""

from __future__ import annotations

import numpy as np

from robolab.datasets.g2o import PoseGraph
from robolab.geometry import compose, relative, transform_points

__all__ = ["simulate_graph"]


def simulate_graph(
    seed: int = 0,
    *,
    laps: int = 3,
    step: float = 1.0,
    size: tuple[float, float] = (12.0, 8.0),
    n_landmarks: int = 30,
    sensor_range: float = 4.0,
    loop_radius: float = 1.0,
    odometry_sigma: tuple[float, float, float] = (0.05, 0.05, 0.02),
    loop_sigma: tuple[float, float, float] = (0.05, 0.05, 0.01),
    landmark_sigma: float = 0.1,
) -> tuple[PoseGraph, np.ndarray, np.ndarray]:
    """Simulate a pose-landmark graph.

    Returns
    -------
    graph : PoseGraph
        The graph with the drifting initial guess.
    true_poses : numpy.ndarray, shape (N, 3)
    true_landmarks : numpy.ndarray, shape (L, 2)
        The truth, for figures and tests (landmarks never seen are dropped).
    """
    rng = np.random.default_rng(seed)
    w, h = size
    # the block's perimeter, walked counter-clockwise in steps of `step`, turning at corners
    corners = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    per_side = [int(round(w / step)), int(round(h / step))] * 2
    truth = []
    for _ in range(laps):
        for c, n in zip(range(4), per_side, strict=True):
            a, b = corners[c], corners[(c + 1) % 4]
            heading = np.arctan2(*(b - a)[::-1])
            for k in range(n):
                truth.append([*(a + (b - a) * k / n), heading])
    truth = np.array(truth + [truth[0]])
    n = len(truth)
    sig_o, sig_l = np.array(odometry_sigma), np.array(loop_sigma)

    odo = relative(truth[:-1], truth[1:]) + rng.normal(0, 1, (n - 1, 3)) * sig_o
    pairs = [(i, i + 1) for i in range(n - 1)]
    loops = [
        (j, i)
        for i in range(n)
        for j in range(i - 2)
        if np.hypot(*(truth[i, :2] - truth[j, :2])) < loop_radius and i - j > 5
    ]
    loop_z = relative(truth[[j for j, _ in loops]], truth[[i for _, i in loops]]).reshape(-1, 3)
    loop_z = loop_z + rng.normal(0, 1, loop_z.shape) * sig_l
    measurements = np.concatenate([odo, loop_z])
    sigmas = np.concatenate([np.tile(sig_o, (n - 1, 1)), np.tile(sig_l, (len(loops), 1))])
    information = np.einsum("ek,kj->ekj", 1.0 / sigmas**2, np.eye(3))

    margin = sensor_range / 2
    landmarks = rng.uniform([-margin, -margin], [w + margin, h + margin], (n_landmarks, 2))
    # every landmark in every pose's frame: (N, L, 2)
    local = transform_points(landmarks, relative(truth, np.zeros(3)))
    seen = np.hypot(local[..., 0], local[..., 1]) < sensor_range
    pose_of, lm_of = np.nonzero(seen)
    keep = np.unique(lm_of)
    remap = np.full(n_landmarks, -1)
    remap[keep] = np.arange(len(keep))
    lm_z = local[pose_of, lm_of] + rng.normal(0, landmark_sigma, (len(pose_of), 2))

    guess = [truth[0]]
    for z in odo:
        guess.append(compose(guess[-1], z))
    guess = np.array(guess)
    first = np.array([np.flatnonzero(lm_of == k)[0] for k in keep], dtype=int)
    lm_guess = np.array(
        [transform_points(lm_z[f][None], guess[pose_of[f]])[0] for f in first]
    ).reshape(-1, 2)

    graph = PoseGraph(
        poses=guess,
        edges=np.array(pairs + loops).reshape(-1, 2),
        measurements=measurements,
        information=information,
        landmarks=lm_guess,
        landmark_edges=np.column_stack([pose_of, remap[lm_of]]),
        landmark_measurements=lm_z,
        landmark_information=np.broadcast_to(np.eye(2) / landmark_sigma**2, (len(pose_of), 2, 2)),
    )
    return graph, truth, landmarks[keep]
