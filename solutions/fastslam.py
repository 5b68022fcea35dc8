r"""Lab 07 reference solution: FastSLAM 1.0 with known correspondences.

Seed 003 (the ME465 extra lab), Probabilistic Robotics Table 13.1. The robot is
:class:`robolab.fiducials.FiducialRobot`: a unicycle that measures the range,
bearing and identity of the fiducials it sees.

FastSLAM factors the SLAM posterior (Probabilistic Robotics eq. 13.8):

.. math::

    p(x_{1:t}, m \mid z_{1:t}, u_{1:t}, c_{1:t})
      = p(x_{1:t} \mid z_{1:t}, u_{1:t}, c_{1:t})
        \prod_{j=1}^{K} p(m_j \mid x_{1:t}, z_{1:t}, c_{1:t}),

a particle filter over robot paths and, inside every particle, one small
2 x 2 EKF per landmark (conditioned on that particle's path the landmarks are
independent).

The filter's state is plain arrays (a dict), never a list of objects:

============  ================  =====================================================
key           shape             meaning
============  ================  =====================================================
``poses``     (M, 3)            pose ``(x, y, theta)`` of each particle
``means``     (M, K, 2)         landmark means :math:`\mu_{k,j}` (metres)
``covs``      (M, K, 2, 2)      landmark covariances :math:`\Sigma_{k,j}` (m^2)
``seen``      (M, K) bool       landmark j has a Gaussian belief in particle k
``weights``   (M,)              importance weights, summing to one
============  ================  =====================================================

Two typos of the seed's handout are corrected here (and pointed out in the
notebook): the innovation is :math:`e = z - \hat z` (the handout's
:math:`e = \hat z - z` with :math:`\mu + K e` moves the landmark the wrong way),
and the weight is :math:`|2\pi Q|^{-1/2} \exp(-\tfrac12 e^T Q^{-1} e)` (the
handout has :math:`|2\pi Q|^{+1/2}` and :math:`e^T Q e`).

Every function works on all particles at once: the only Python loops are over
time steps and over rounds of repeated landmark ids within one step.
"""

from __future__ import annotations

import numpy as np

from robolab.fiducials import DT, as_robot, sqrt_psd
from robolab.geometry import wrap_angle
from robolab.validation import (
    all_finite,
    as_array,
    as_observations,
    check_count,
    check_covariance,
    check_covariance_stack,
    check_positive,
    check_rng,
)

__all__ = [
    "init_particles",
    "predict_poses",
    "h",
    "h_jacobian",
    "update_landmark",
    "fastslam_step",
    "fastslam",
]

#: The seed's prior of an unseen landmark: mu0 = 0, Sigma0 = 10000 I (m^2).
SIGMA0 = 10000.0
#: Log of the book's importance factor p0 for a landmark seen for the first time
#: (Table 13.1, line 10). It is the same in every particle (all particles see the
#: same landmarks, correspondences are known), so it cancels when normalizing.
LOG_P0 = 0.0
#: Smallest squared range used in h's Jacobian, m^2 (a landmark on the robot is undefined).
MIN_SQ_RANGE = 1e-12
#: fastslam_step updates at most about this many (particle, landmark) pairs at a time: its
#: EKF_WORK scratch arrays take 4.5 MB at most (fewer, longer numpy calls: 2^15 measured
#: 1.1-1.3x faster than 2^13 or 2^12 at 1000 particles x 22 observations).
EKF_BLOCK = 1 << 15
INIT_MODES = ("prior", "first_observation")
STATE_KEYS = ("poses", "means", "covs", "seen", "weights")


def init_particles(n_particles, n_landmarks, x0, init="prior"):
    r"""Create the initial FastSLAM particle set (seed 003, "Data Structure Initialization").

    Every particle starts at the known pose :math:`x_0` (SLAM fixes the map's
    frame by the start pose) with equal weight :math:`1/M`.

    ``init="prior"`` (the seed): every landmark has the vague Gaussian belief
    :math:`\mu_0 = 0`, :math:`\Sigma_0 = 10^4 I`, so ``seen`` is all True and the
    first observation is an ordinary EKF update from that prior.

    ``init="first_observation"`` (the book, Table 13.1 lines 7-10): no landmark
    has a belief yet (``seen`` all False; ``means`` and ``covs`` hold the
    placeholders 0 and :math:`10^4 I`); the first observation of landmark j
    initializes it by inverting the measurement model,
    :math:`\mu = h^{-1}(z, x)`, :math:`\Sigma = H^{-1} Q_t H^{-T}`.

    Parameters
    ----------
    n_particles : int
        Number of particles M >= 1.
    n_landmarks : int
        Number of landmarks K >= 1.
    x0 : array_like, shape (3,)
        Start pose ``(x, y, theta)``.
    init : {"prior", "first_observation"}
        How landmarks start (see above).

    Returns
    -------
    dict of numpy arrays
        ``poses`` (M, 3), ``means`` (M, K, 2), ``covs`` (M, K, 2, 2),
        ``seen`` (M, K) bool, ``weights`` (M,); every array is its own copy.
    """
    m = check_count("n_particles", n_particles)
    k = check_count("n_landmarks", n_landmarks)
    pose = as_array("x0", x0, shape=(3,), finite=True).copy()
    pose[2] = wrap_angle(pose[2])
    if init not in INIT_MODES:
        raise ValueError(f"init must be one of {INIT_MODES}, got {init!r}")
    return {
        "poses": np.tile(pose, (m, 1)),
        "means": np.zeros((m, k, 2)),
        "covs": np.broadcast_to(SIGMA0 * np.eye(2), (m, k, 2, 2)).copy(),
        "seen": np.full((m, k), init == "prior"),
        "weights": np.full(m, 1.0 / m),
    }


def predict_poses(poses, command, Q, rng, dt=DT):
    r"""Sample every particle's next pose from the lab's motion model (Table 13.1, line 4).

    The fiducial robot's unicycle model with additive Gaussian pose noise
    (the same model :mod:`robolab.fiducials` simulates):

    .. math::

        \begin{pmatrix} x' \\ y' \\ \theta' \end{pmatrix} =
        \begin{pmatrix} x + v\,\Delta t \cos\theta \\ y + v\,\Delta t \sin\theta \\
        \theta + \omega\,\Delta t \end{pmatrix} + w, \qquad w \sim \mathcal N(0, Q),

    independently for each particle, with :math:`\theta'` wrapped to
    :math:`[-\pi, \pi)`.

    Parameters
    ----------
    poses : array_like, shape (M, 3)
        Particle poses; not modified.
    command : array_like, shape (2,)
        ``[v, omega]`` in m/s and rad/s.
    Q : array_like, shape (3, 3)
        Symmetric positive semi-definite noise covariance per step (zeros: no noise).
    rng : numpy.random.Generator
        Source of the noise.
    dt : float
        Time step in seconds.

    Returns
    -------
    numpy.ndarray, shape (M, 3)
        The sampled poses, a new array.
    """
    return _predict(_poses(poses), command, Q, rng, dt)


def h(landmark, pose):
    r"""Range-bearing measurement :math:`\hat z = h(\mu_j, x)` (Probabilistic Robotics eq. 6.40).

    .. math::

        \hat r = \sqrt{(\mu_x - x)^2 + (\mu_y - y)^2}, \qquad
        \hat\phi = \operatorname{wrap}\big(\operatorname{atan2}(\mu_y - y, \mu_x - x) - \theta\big)

    Broadcasts over leading dimensions (for example ``landmark`` (M, 2) and
    ``pose`` (M, 3) for all particles at once).

    Parameters
    ----------
    landmark : array_like, shape (..., 2)
        Landmark position(s) :math:`\mu_j`, metres.
    pose : array_like, shape (..., 3)
        Robot pose(s) ``(x, y, theta)``.

    Returns
    -------
    numpy.ndarray, shape (..., 2)
        ``[range, bearing]``; bearing wrapped to ``[-pi, pi)``.
    """
    return _range_bearing(_last_dim("landmark", landmark, 2), _last_dim("pose", pose, 3))


def h_jacobian(landmark, pose):
    r"""Jacobian :math:`H = \partial h(\mu_j, x) / \partial \mu_j` with respect to the landmark.

    With :math:`\delta = \mu_j - (x, y)^T` and :math:`q = \delta^T\delta`
    (Probabilistic Robotics eq. 13.11 restricted to the landmark; the seed's
    hints give the bearing row):

    .. math::

        H = \begin{pmatrix} \delta_x / \sqrt q & \delta_y / \sqrt q \\
                            -\delta_y / q & \delta_x / q \end{pmatrix}

    In the bearing row :math:`q` is floored at :data:`MIN_SQ_RANGE`, and the range
    row is always a unit vector (the x axis for a landmark exactly on the robot),
    so that a landmark estimate on top of the robot gives a large but finite
    Jacobian whose inverse stays bounded; :math:`\sqrt q` is computed with
    ``hypot``, which does not overflow for far landmarks.

    Parameters
    ----------
    landmark : array_like, shape (..., 2)
    pose : array_like, shape (..., 3)

    Returns
    -------
    numpy.ndarray, shape (..., 2, 2)
        Row 0 is the range's gradient, row 1 the bearing's.
    """
    return _range_bearing_jacobian(_last_dim("landmark", landmark, 2), _last_dim("pose", pose, 3))


def update_landmark(mean, cov, z, pose, Qt):
    r"""EKF update of one landmark's Gaussian, and the log-likelihood (Table 13.1, lines 12-19).

    .. math::

        \hat z &= h(\mu, x), \quad H = \partial h / \partial \mu, \quad
        Q = H \Sigma H^T + Q_t, \quad K = \Sigma H^T Q^{-1} \\
        e &= z - \hat z \quad (\text{bearing wrapped to } [-\pi, \pi)) \\
        \mu' &= \mu + K e, \qquad \Sigma' = (I - K H)\,\Sigma \\
        \ln w &= -\tfrac12 \ln|2\pi Q| - \tfrac12 e^T Q^{-1} e

    so :math:`w = |2\pi Q|^{-1/2}\exp(-\frac12 e^T Q^{-1} e)`, the Gaussian
    density of the innovation. The seed's handout prints
    :math:`|2\pi Q|^{+1/2}\exp(-\frac12 e^T Q e)` and :math:`e = \hat z - z`:
    both are typos. Without the wrap, a bearing measured as 3.1 rad and predicted
    as -3.1 rad (0.08 rad apart) would look 6.2 rad apart.

    The likelihood is returned as its logarithm: for a landmark estimate metres
    away from the measurement it is :math:`e^{-1000}` or less, which underflows
    to 0 in every particle; the log stays finite and the filter normalizes
    with the log-sum-exp trick.

    Broadcasts over leading dimensions, e.g. ``mean`` (M, 2), ``cov``
    (M, 2, 2), ``pose`` (M, 3) and one ``z`` (2,) for all particles.

    Parameters
    ----------
    mean : array_like, shape (..., 2)
        Landmark mean :math:`\mu`, metres.
    cov : array_like, shape (..., 2, 2)
        Landmark covariance :math:`\Sigma` (symmetric positive definite).
    z : array_like, shape (..., 2)
        Measurement ``[range, bearing]``.
    pose : array_like, shape (..., 3)
        The particle's pose.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance.

    Returns
    -------
    mean : numpy.ndarray, shape (..., 2)
    cov : numpy.ndarray, shape (..., 2, 2)
        Symmetrized.
    log_likelihood : numpy.ndarray, shape (...)
        :math:`\ln \mathcal N(z; \hat z, Q)`, finite.
    """
    mu = _last_dim("mean", mean, 2)
    sigma = check_covariance_stack("cov", cov, 2, definite=True)
    zz = _last_dim("z", z, 2)
    p = _last_dim("pose", pose, 3)
    qt = check_covariance("Qt", Qt, 2, definite=True)
    out = _ekf_update(mu, sigma, zz, p, qt)
    _check_update(out, "the update")
    return out


def fastslam_step(state, command, observations, Q, Qt, rng, dt=DT, resample=True):
    r"""One step of FastSLAM 1.0 with known correspondences (Probabilistic Robotics Table 13.1).

    1. Sample each particle's pose from the motion model (:func:`predict_poses`).
    2. For every observation ``[r, phi, j]``, in every particle at once: if
       landmark j has a belief, EKF-update it (:func:`update_landmark`) and
       multiply the weight by the likelihood; otherwise initialize it from the
       observation, :math:`\mu = (x + r\cos(\theta+\phi), y + r\sin(\theta+\phi))`,
       :math:`\Sigma = H^{-1} Q_t H^{-T}`, weight factor :math:`p_0`. Landmarks not
       observed are left alone. Observations of different landmarks are
       processed together; a repeated id waits for the next round.
    3. Normalize the weights in log space:
       :math:`w_k = \exp(\ell_k - \max\ell) / \sum_i \exp(\ell_i - \max\ell)` with
       :math:`\ell_k = \ln w_k^{old} + \sum \ln \mathcal N(z; \hat z, Q)`, so the
       weights stay finite even when every likelihood underflows.
    4. Resample with the low-variance sampler (Table 4.4), unless ``resample``
       is False or there was no observation (then the weights did not change).
       With a number for ``resample``, resample only when the effective sample
       size :math:`N_{eff} = 1 / \sum_k w_k^2` falls below ``resample * M``
       (selective resampling, Grisetti et al. 2007; ``0.5`` is the usual
       choice): resampling after every measurement throws away particles that
       are nearly as good as the kept ones and depletes the paths.
       Resampling copies the chosen particles' arrays (fancy indexing): no two
       particles share landmark memory, and the input ``state`` is not modified.

    Parameters
    ----------
    state : dict
        ``poses``, ``means``, ``covs``, ``seen``, ``weights`` as made by
        :func:`init_particles`.
    command : array_like, shape (2,)
        ``[v, omega]``.
    observations : array_like, shape (k, 3)
        Rows ``[range, bearing, id]`` (``k`` may be 0; ``None`` means none).
    Q : array_like, shape (3, 3)
        Motion noise covariance.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance.
    rng : numpy.random.Generator
    dt : float
        Time step in seconds.
    resample : bool or float
        True (default): resample after every step with an observation, as the
        book. False: never; the new state keeps the normalized importance
        weights. A number in (0, 1]: resample only when
        :math:`N_{eff} <` ``resample * M`` (0.5: below half the particles).

    Returns
    -------
    dict
        The new state (new arrays). After resampling the weights are uniform.
    """
    s = _check_state(state)
    n_landmarks = s["means"].shape[1]
    obs = _observations(observations, n_landmarks)
    qt, _ = _noise("Qt", Qt, 2, definite=True)
    poses = _predict(s["poses"], command, Q, rng, dt)  # checks command, Q, rng, dt
    log_w = np.log(s["weights"], out=np.full_like(s["weights"], -np.inf), where=s["weights"] > 0)
    ess = _ess_fraction(resample)
    # Work on copies of the observed landmarks' columns only; the full arrays are
    # copied once, at the end (gathered by the resampling indices when resampling).
    touched, cols = np.unique(obs[:, 2].astype(np.intp), return_inverse=True)
    # np.take on axis 1: several times faster than the equivalent fancy index [:, touched]
    means, covs, seen = (np.take(s[key], touched, axis=1) for key in ("means", "covs", "seen"))
    ids = cols.reshape(-1)
    remaining = np.arange(len(obs))
    while remaining.size:  # rounds of distinct landmark ids (one round unless ids repeat)
        _, first = np.unique(ids[remaining], return_index=True)
        batch, remaining = remaining[first], np.delete(remaining, first)
        j, z = ids[batch], obs[batch, :2]
        whole = len(j) == len(touched)  # then j is 0, 1, ..., n - 1: update in place
        mu, sigma, known = (a if whole else np.take(a, j, axis=1) for a in (means, covs, seen))
        log_like = np.empty(known.shape)
        _blocked_ekf_update(mu, sigma, z, poses, qt, log_like)
        if not known.all():
            init_mu, init_sigma = _landmark_from_observation(z[None], poses[:, None, :], qt)
            np.copyto(mu, init_mu, where=~known[..., None])
            np.copyto(sigma, init_sigma, where=~known[..., None, None])
            np.copyto(log_like, LOG_P0, where=~known)
        what = lambda rows=obs[batch]: f"observations {rows.tolist()}"  # noqa: E731 - on error
        _check_update((mu, sigma, log_like), what)
        if whole:
            seen[...] = True
        else:
            means[:, j], covs[:, j], seen[:, j] = mu, sigma, True
        log_w = log_w + log_like.sum(axis=1)
    weights = _normalize_log_weights(log_w)
    do_resample = bool(resample) and len(obs) > 0 and (
        ess is None or 1.0 / np.sum(weights**2) < ess * len(weights)
    )
    idx = _low_variance_resample(weights, rng) if do_resample else slice(None)
    new = {"poses": poses[idx]}
    for key, part in (("means", means), ("covs", covs), ("seen", seen)):
        if isinstance(idx, slice):
            new[key] = s[key].copy()
            _pairs(new[key])[:, touched] = _pairs(part)
        else:  # np.take copies whole rows: faster than the fancy index [idx]
            new[key] = np.take(s[key], idx, axis=0)
            _pairs(new[key])[:, touched] = np.take(_pairs(part), idx, axis=0)
    new["weights"] = weights if isinstance(idx, slice) else np.full(len(poses), 1.0 / len(poses))
    return new


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
        path.append(_mean_pose(state["poses"], state["weights"]))
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


# -- private helpers -------------------------------------------------------------


def _poses(poses) -> np.ndarray:
    p = as_array("poses", poses, ndim=2, finite=True)
    if p.shape[1] != 3:
        raise ValueError(f"poses must have shape (M, 3), got {p.shape}")
    return p


def _last_dim(name, value, n) -> np.ndarray:
    arr = as_array(name, value, finite=True)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got {arr.shape}")
    return arr


def _inv2_entries(a00, a01, a10, a11):
    """Entries of the inverse and the log-determinant of 2 x 2 matrices given entry-wise.

    Each matrix is scaled by its largest entry first, so that entries of 1e-300
    or 1e200 neither underflow nor overflow in the determinant:
    ``inv(s A') = inv(A') / s`` and ``log|s A'| = 2 log s + log|A'|``.
    Returns ``((i00, i01, i10, i11), logdet)``.
    """
    s = np.maximum(np.maximum(np.abs(a00), np.abs(a01)), np.maximum(np.abs(a10), np.abs(a11)))
    s = np.where(s > 0, s, 1.0)
    b00, b01, b10, b11 = a00 / s, a01 / s, a10 / s, a11 / s
    det = b00 * b11 - b01 * b10
    with np.errstate(divide="ignore", invalid="ignore"):
        f = 1.0 / (det * s)
        return (b11 * f, -b01 * f, -b10 * f, b00 * f), 2.0 * np.log(s) + np.log(det)


def _inv2(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse and log-determinant of a stack of 2 x 2 matrices (:func:`_inv2_entries`)."""
    (i00, i01, i10, i11), logdet = _inv2_entries(a[..., 0, 0], a[..., 0, 1], a[..., 1, 0],
                                                  a[..., 1, 1])
    inv = np.empty(a.shape, dtype=np.result_type(a, float))
    inv[..., 0, 0], inv[..., 0, 1], inv[..., 1, 0], inv[..., 1, 1] = i00, i01, i10, i11
    return inv, logdet


def _ekf_update(mu, sigma, zz, p, qt):
    r"""The body of :func:`update_landmark` on checked arrays (broadcast; new arrays).

    Returns ``(new_mean, new_cov, log_likelihood)``, computed by :func:`_ekf_entries`.
    """
    shape = np.broadcast_shapes(mu.shape[:-1], sigma.shape[:-2], zz.shape[:-1], p.shape[:-1])
    new_mean, new_cov, log_like = np.empty(shape + (2,)), np.empty(shape + (2, 2)), np.empty(shape)
    _ekf_entries(
        _entries(mu, sigma),
        (p[..., 0], p[..., 1], p[..., 2], zz[..., 0], zz[..., 1]),
        qt,
        _entries(new_mean, new_cov) + (log_like,),
        np.empty((EKF_WORK,) + shape),
    )
    return new_mean, new_cov, log_like


def _entries(mean, cov):
    """Views ``(mu0, mu1, s00, s01, s10, s11)`` of means (..., 2) and covariances (..., 2, 2)."""
    s = cov
    return mean[..., 0], mean[..., 1], s[..., 0, 0], s[..., 0, 1], s[..., 1, 0], s[..., 1, 1]


#: How many scratch arrays :func:`_ekf_entries` takes.
EKF_WORK = 17


def _ekf_entries(landmark, observer, qt, out, work):
    r"""The EKF update of :func:`update_landmark`, entry by entry, into ``out``.

    ``landmark`` holds the entries ``(mu0, mu1, s00, s01, s10, s11)`` of the
    means and covariances (:func:`_entries`), ``observer`` the pose and
    measurement ``(x, y, theta, r, phi)``, all broadcasting to the shape of the
    ``EKF_WORK`` scratch arrays in ``work``. ``out`` receives the updated entries
    and the log-likelihood, ``(mu0', mu1', s00', s01', s10', s11', ln w)``, and may
    be the input entries themselves (an update in place: each input is last read
    before its output is written).

    The batched 2 x 2 products are written out entry by entry (numpy's ``@`` on
    stacks of 2 x 2 matrices costs several times the arithmetic itself), each
    into a scratch array (``out=``: no temporaries to allocate). With
    :math:`H = \begin{pmatrix} a & b \\ c & d \end{pmatrix}` (:func:`h_jacobian`),
    :math:`P = \Sigma H^T`, :math:`Q = H P + Q_t`, :math:`K = P Q^{-1}`,
    :math:`\mu' = \mu + K e`, :math:`\Sigma' = \Sigma - (K H) \Sigma`
    (symmetrized), :math:`\ln w = -\tfrac12 e^T Q^{-1} e - \ln 2\pi - \tfrac12 \ln|Q|`.
    The geometry uses ``hypot`` (no overflow of the squared range) and :math:`Q` is
    inverted as :func:`_inv2_entries` does (scaled by its largest entry: no under- or
    overflow of its determinant), with the same roundings: the negative entries
    :math:`c = -b/r`, :math:`Q^{-1}_{01}` and :math:`Q^{-1}_{10}` are kept as their
    magnitudes and subtracted (``x + (-y)`` is ``x - y`` in floating point).
    """
    mu0, mu1, s00, s01, s10, s11 = landmark
    x, y, theta, r, phi = observer
    a, b, nc, d, e0, t, u, s, v, p00, p01, p10, p11, q00, q01, q10, q11 = (
        work[i, ...] for i in range(EKF_WORK)  # 0-d arrays for one pair, not scalars
    )
    # z_hat = h(mu, x) and H = dh/dmu (the bodies of h and h_jacobian, sharing dx, dy)
    np.subtract(mu0, x, out=a)  # dx
    np.subtract(mu1, y, out=b)  # dy
    np.hypot(a, b, out=d)  # the range
    np.subtract(r, d, out=e0)
    np.arctan2(b, a, out=t)
    np.subtract(t, theta, out=t)
    e1 = wrap_angle(phi - wrap_angle(t))
    nearest = d.min() if d.size else np.inf  # NaN if a range is: fails both tests below
    if nearest > 0:  # the usual case: no landmark estimate on top of its particle
        np.divide(a, d, out=a)
        np.divide(b, d, out=b)
    else:  # the unit direction, the x axis at range 0 (NaN fails d > 0 as it does min() > 0)
        safe = d > 0
        den = np.where(safe, d, 1.0)
        a[...] = np.where(safe, a / den, 1.0)
        b[...] = np.where(safe, b / den, 0.0)
    if not nearest >= np.sqrt(MIN_SQ_RANGE):
        np.maximum(d, np.sqrt(MIN_SQ_RANGE), out=d)  # the bearing's rate 1 / r, bounded
    np.divide(b, d, out=nc)  # c = -nc
    np.divide(a, d, out=d)
    # P = Sigma H^T
    _sum_of_products(s00, a, s01, b, t, out=p00)
    _sum_of_products(s01, d, s00, nc, t, out=p01, subtract=True)
    _sum_of_products(s10, a, s11, b, t, out=p10)
    _sum_of_products(s11, d, s10, nc, t, out=p11, subtract=True)
    # Q = H P + Q_t
    _sum_of_products(a, p00, b, p10, t, out=q00)
    _sum_of_products(a, p01, b, p11, t, out=q01)
    _sum_of_products(d, p10, nc, p00, t, out=q10, subtract=True)
    _sum_of_products(d, p11, nc, p01, t, out=q11, subtract=True)
    for q, add in ((q00, qt[0, 0]), (q01, qt[0, 1]), (q10, qt[1, 0]), (q11, qt[1, 1])):
        np.add(q, add, out=q)
    # Q^-1 as _inv2_entries: scale s, entries q / s, f = 1 / (det s); i01 = -j01, i10 = -j10
    np.abs(q00, out=s)
    np.maximum(s, np.abs(q01, out=t), out=s)
    np.maximum(np.abs(q10, out=t), np.abs(q11, out=u), out=t)
    np.maximum(s, t, out=s)
    if not (s.size and s.min() > 0):
        np.copyto(s, 1.0, where=~(s > 0))
    for q in (q00, q01, q10, q11):
        np.divide(q, s, out=q)
    _sum_of_products(q00, q11, q01, q10, t, out=u, subtract=True)  # det
    with np.errstate(divide="ignore", invalid="ignore"):
        np.divide(1.0, np.multiply(u, s, out=t), out=t)  # f
        i00, i11, j01, j10 = np.multiply(q11, t, out=v), q11, q01, q10
        np.multiply(q00, t, out=i11)
        np.multiply(q01, t, out=j01)
        np.multiply(q10, t, out=j10)
        logdet = np.log(s, out=s)
        np.multiply(logdet, 2.0, out=logdet)
        np.add(logdet, np.log(u, out=u), out=logdet)
    # K = P Q^-1
    k00, k01, k10, k11 = q00, u, p00, p01
    _sum_of_products(p00, i00, p01, j10, t, out=k00, subtract=True)
    _sum_of_products(p01, i11, p00, j01, t, out=k01, subtract=True)
    _sum_of_products(p10, i00, p11, j10, t, out=k10, subtract=True)
    _sum_of_products(p11, i11, p10, j01, t, out=k11, subtract=True)
    with np.errstate(over="ignore", invalid="ignore"):  # a huge range: refused by the caller
        maha = _sum_of_products(i00, e0, j01, e1, t, out=p10, subtract=True)
        np.multiply(maha, e0, out=maha)
        _sum_of_products(i11, e1, j10, e0, t, out=p11, subtract=True)
        np.multiply(p11, e1, out=p11)
        np.add(maha, p11, out=maha)
    # mu' = mu + K e
    new_mu0, new_mu1, new_s00, new_s01, new_s10, new_s11, log_like = out
    np.add(np.add(mu0, np.multiply(k00, e0, out=t), out=t), np.multiply(k01, e1, out=p11),
           out=new_mu0)
    np.add(np.add(mu1, np.multiply(k10, e0, out=t), out=t), np.multiply(k11, e1, out=p11),
           out=new_mu1)
    np.subtract(np.multiply(maha, -0.5, out=maha), np.log(2.0 * np.pi), out=maha)
    np.subtract(maha, np.multiply(logdet, 0.5, out=logdet), out=log_like)
    # Sigma' = Sigma - (K H) Sigma, symmetrized
    m00, m01, m10, m11 = p10, p11, q01, q10
    _sum_of_products(k00, a, k01, nc, t, out=m00, subtract=True)
    _sum_of_products(k00, b, k01, d, t, out=m01)
    _sum_of_products(k10, a, k11, nc, t, out=m10, subtract=True)
    _sum_of_products(k10, b, k11, d, t, out=m11)
    _sum_of_products(m00, s01, m01, s11, t, out=k10)
    np.subtract(s01, k10, out=k10)
    _sum_of_products(m10, s00, m11, s10, t, out=k11)
    np.subtract(s10, k11, out=k11)
    off = np.multiply(np.add(k10, k11, out=k10), 0.5, out=k10)
    _sum_of_products(m00, s00, m01, s10, t, out=k00)
    _sum_of_products(m10, s01, m11, s11, t, out=k01)
    np.subtract(s00, k00, out=new_s00)
    np.subtract(s11, k01, out=new_s11)
    np.copyto(new_s01, off)
    np.copyto(new_s10, off)


def _sum_of_products(w, x, y, z, tmp, out, subtract=False):
    """``w x + y z`` (or ``w x - y z``) into ``out``, rounded as numpy's ``w * x + y * z``."""
    np.multiply(w, x, out=out)
    np.multiply(y, z, out=tmp)
    return (np.subtract if subtract else np.add)(out, tmp, out=out)


def _blocked_ekf_update(means, covs, z, poses, qt, log_like):
    """:func:`_ekf_entries` of (M, b) landmarks in place (``means``, ``covs``; the
    log-likelihoods into ``log_like``), about ``EKF_BLOCK`` pairs at a time, all blocks
    sharing one set of scratch arrays."""
    m, b = means.shape[:2]
    per = max(1, EKF_BLOCK // max(b, 1))
    work = np.empty((EKF_WORK, min(per, m), b))
    for i in range(0, m, per):
        rows = slice(i, i + per)
        block = _entries(means[rows], covs[rows])
        pose = poses[rows, None, :]
        _ekf_entries(
            block,
            (pose[..., 0], pose[..., 1], pose[..., 2], z[:, 0], z[:, 1]),
            qt,
            block + (log_like[rows],),
            work[:, : len(pose)],
        )


def _pairs(a: np.ndarray) -> np.ndarray:
    """A C-contiguous float array (M, K, 2, ...) viewed as complex (M, K, ...), one element per
    pair of floats (fancy indexing then moves half as many elements); bool arrays as they are."""
    return a.view(np.complex128)[..., 0] if a.dtype == np.float64 else a


def _ess_fraction(resample) -> float | None:
    """None for ``resample`` True / False (always / never), else the ESS fraction in (0, 1]."""
    if isinstance(resample, (bool, np.bool_)):
        return None
    fraction = check_positive("resample", resample)
    if fraction > 1:
        raise ValueError(
            f"resample must be True, False or an ESS fraction in (0, 1], got {resample!r}"
        )
    return fraction


def _check_update(update, what) -> None:
    """Raise if an EKF update or initialization left the range of float64.

    ``what`` names the update in the message: a string, or a callable that makes it.
    """
    mean, cov, log_like = update
    with np.errstate(invalid="ignore"):  # -inf + inf: NaN, then checked entry by entry
        no_nan = not np.isnan(log_like.sum()) or not np.isnan(log_like).any()
    if not (all_finite(mean) and all_finite(cov) and no_nan):
        what = what() if callable(what) else what
        raise ValueError(
            f"{what}: the landmark estimate is not finite in float64 (a range or covariance "
            f"too large or too small for the landmark's mean and covariance)"
        )


def _predict(p, command, Q, rng, dt):
    """:func:`predict_poses` on checked poses."""
    u = as_array("command", command, shape=(2,), finite=True)
    _, q_sqrt = _noise("Q", Q, 3, definite=False)
    check_rng(rng)
    dt = check_positive("dt", dt)
    return _sample_motion(p, u, q_sqrt, rng, dt)


#: Noise covariances already checked, by value (a filter passes the same Q and Qt every step).
_NOISE: dict = {}


def _noise(name, value, n, definite):
    """``check_covariance`` of a noise covariance and a square root of it (:func:`sqrt_psd`),
    both read-only, remembered by value for the last few matrices."""
    c = as_array(name, value, shape=(n, n), finite=True)
    key = (name, definite, c.tobytes())
    known = _NOISE.get(key)
    if known is None:
        c = check_covariance(name, c.copy(), n, definite=definite)
        known = (c, sqrt_psd(c))
        for a in known:
            a.flags.writeable = False
        if len(_NOISE) >= 16:
            _NOISE.clear()
        _NOISE[key] = known
    return known


def _sample_motion(p, u, q_sqrt, rng, dt):
    """The body of :func:`predict_poses` on checked arrays; ``q_sqrt @ q_sqrt.T = Q``."""
    noise = rng.standard_normal(p.shape) @ q_sqrt.T
    out = np.empty_like(p)
    out[:, 0] = p[:, 0] + u[0] * dt * np.cos(p[:, 2]) + noise[:, 0]
    out[:, 1] = p[:, 1] + u[0] * dt * np.sin(p[:, 2]) + noise[:, 1]
    out[:, 2] = wrap_angle(p[:, 2] + u[1] * dt + noise[:, 2])
    return out


def _range_bearing(lm, p):
    """The body of :func:`h` on checked arrays."""
    dx = lm[..., 0] - p[..., 0]
    dy = lm[..., 1] - p[..., 1]
    return np.stack([np.hypot(dx, dy), wrap_angle(np.arctan2(dy, dx) - p[..., 2])], -1)


def _range_bearing_jacobian(lm, p):
    """The body of :func:`h_jacobian` on checked arrays."""
    dx = lm[..., 0] - p[..., 0]
    dy = lm[..., 1] - p[..., 1]
    d = np.hypot(dx, dy)  # no overflow of dx^2 + dy^2
    safe = d > 0
    c = np.where(safe, dx / np.where(safe, d, 1.0), 1.0)  # the unit direction (x axis at d = 0)
    s = np.where(safe, dy / np.where(safe, d, 1.0), 0.0)
    r = np.maximum(d, np.sqrt(MIN_SQ_RANGE))  # the bearing's rate: 1 / r, bounded near the robot
    return np.stack([np.stack([c, s], -1), np.stack([-s / r, c / r], -1)], -2)


def _landmark_from_observation(z, pose, Qt):
    r"""Table 13.1 lines 7-9: :math:`\mu = h^{-1}(z, x)`, :math:`\Sigma = H^{-1} Q_t H^{-T}`."""
    r, phi = z[..., 0], z[..., 1]
    angle = pose[..., 2] + phi
    mu = np.stack([pose[..., 0] + r * np.cos(angle), pose[..., 1] + r * np.sin(angle)], -1)
    mu = np.broadcast_to(mu, np.broadcast_shapes(mu.shape, pose.shape[:-1] + (2,)))
    H_inv, _ = _inv2(_range_bearing_jacobian(mu, pose))
    with np.errstate(over="ignore", invalid="ignore"):  # a huge range: checked by the caller
        return mu.copy(), H_inv @ Qt @ np.swapaxes(H_inv, -1, -2)


def _normalize_log_weights(log_w: np.ndarray) -> np.ndarray:
    """``exp(log_w - max) / sum``: finite and summing to one unless every entry is -inf."""
    top = np.max(log_w)
    if not np.isfinite(top):
        raise ValueError("every particle has zero weight (log-weights all -inf or NaN)")
    w = np.exp(log_w - top)
    return w / w.sum()


def _low_variance_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices drawn by the low-variance sampler (Probabilistic Robotics Table 4.4)."""
    m = len(weights)
    pointers = rng.uniform(0.0, 1.0 / m) + np.arange(m) / m
    idx = np.searchsorted(np.cumsum(weights), pointers, side="left")
    return np.minimum(idx, m - 1)


def _check_state(state) -> dict:
    if not isinstance(state, dict):
        raise TypeError(f"state must be a dict with keys {STATE_KEYS}, got {type(state).__name__}")
    missing = [k for k in STATE_KEYS if k not in state]
    if missing:
        raise ValueError(f"state is missing {', '.join(missing)} (make it with init_particles)")
    poses = _poses(state["poses"])
    m = poses.shape[0]
    means = as_array("state['means']", state["means"], ndim=3, finite=True)
    k = means.shape[1]
    if means.shape != (m, k, 2):
        raise ValueError(
            f"state['means'] must have shape (M, K, 2) = ({m}, K, 2), got {means.shape}"
        )
    covs = as_array("state['covs']", state["covs"], shape=(m, k, 2, 2), finite=True)
    seen = np.asarray(state["seen"])
    if seen.shape != (m, k) or seen.dtype != bool:
        raise ValueError(
            f"state['seen'] must be a bool array of shape ({m}, {k}), got {seen.dtype} {seen.shape}"
        )
    weights = as_array(
        "state['weights']", state["weights"], shape=(m,), finite=True, nonnegative=True
    )
    if abs(weights.sum() - 1.0) > 1e-6:
        raise ValueError(f"state['weights'] must sum to 1, got {weights.sum()}")
    return {"poses": poses, "means": means, "covs": covs, "seen": seen, "weights": weights}


def _observations(observations, n_landmarks) -> np.ndarray:
    return as_observations("observations", observations, n_landmarks)


def _mean_pose(poses: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Weighted mean pose; the heading is the circular mean, wrapped."""
    xy = weights @ poses[:, :2]
    theta = np.arctan2(weights @ np.sin(poses[:, 2]), weights @ np.cos(poses[:, 2]))
    return np.array([xy[0], xy[1], wrap_angle(theta)])
