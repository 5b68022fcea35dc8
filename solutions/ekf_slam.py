r"""Lab 08 reference solution: EKF-SLAM with known correspondences.

Past the seeds: Probabilistic Robotics Table 10.1 (EKF SLAM with known
correspondences), with the odometry motion model ``(r1, t, r2)`` as a second
motion model for the Freiburg course data. The robot of the simulated part is
lab 07's :class:`robolab.fiducials.FiducialRobot`, so that FastSLAM and
EKF-SLAM run on the same data.

The belief is one Gaussian over the pose and every landmark:

=========  ==================  ===================================================
name       shape               meaning
=========  ==================  ===================================================
``mu``     (3 + 2K,)           ``(x, y, theta, m_0x, m_0y, ..., m_(K-1)x, m_(K-1)y)``
``sigma``  (3 + 2K, 3 + 2K)    its covariance (m^2, m rad, rad^2)
=========  ==================  ===================================================

Landmark ``j`` occupies entries ``3 + 2j`` and ``4 + 2j``. A landmark not seen
yet has no belief: its entries are placeholders that nothing reads (its rows and
columns of ``sigma`` are zero), and :func:`add_landmark` writes them at its
first sighting. This is the limit of the book's initialization with an infinite
prior covariance (Table 10.1 with eq. 10.10), computed without the infinity.

Costs: :func:`predict` touches only the pose block and the pose-landmark cross
blocks, O(K); :func:`correct` changes every entry of ``sigma``, O(k K^2) for k
observations. No function loops over the state's landmarks in Python.
"""

from __future__ import annotations

import numpy as np

from robolab.fiducials import DT, as_robot
from robolab.geometry import wrap_angle
from robolab.validation import as_array, as_observations, check_covariance, check_positive

__all__ = ["predict", "observation", "correct", "add_landmark", "ekf_slam"]

MOTIONS = ("unicycle", "odometry")


def predict(mu, sigma, command, R, dt=DT, motion="unicycle"):
    r"""EKF-SLAM prediction: move the pose, leave the landmarks (Table 10.1, lines 2-5).

    With :math:`F_x` the :math:`3 \times (3 + 2K)` matrix that selects the pose,

    .. math::

        \bar\mu = \mu + F_x^T\,\Delta(\mu, u), \qquad
        \bar\Sigma = G\,\Sigma\,G^T + F_x^T R\,F_x, \qquad
        G = I + F_x^T\,\frac{\partial \Delta}{\partial x}\,F_x .

    ``motion="unicycle"`` (the fiducial robot, ``command = (v, omega)``):
    :math:`\Delta = (v\,\Delta t\cos\theta,\ v\,\Delta t\sin\theta,\ \omega\,\Delta t)`.
    ``motion="odometry"`` (Table 5.6's parameters, ``command = (r1, t, r2)``,
    ``dt`` unused): :math:`\Delta = (t\cos(\theta + r_1),\ t\sin(\theta + r_1),\
    r_1 + r_2)`. In both, the pose Jacobian :math:`G_x = \partial g / \partial x`
    differs from the identity only in its third column.

    Only the pose block and the pose-landmark cross blocks change:
    :math:`\bar\Sigma_{xx} = G_x \Sigma_{xx} G_x^T + R`,
    :math:`\bar\Sigma_{xm} = G_x \Sigma_{xm}`, :math:`\bar\Sigma_{mm} = \Sigma_{mm}`,
    which costs O(K), not the O(K^3) of multiplying by the full :math:`G`.

    Parameters
    ----------
    mu : array_like, shape (3 + 2K,)
        State mean, K >= 1; not modified.
    sigma : array_like, shape (3 + 2K, 3 + 2K)
        State covariance (symmetric); not modified.
    command : array_like, shape (2,) or (3,)
        ``(v, omega)`` in m/s and rad/s, or ``(r1, t, r2)`` in rad, m, rad.
    R : array_like, shape (3, 3)
        Motion noise covariance in the pose's coordinates (symmetric PSD).
    dt : float
        Time step in seconds (unicycle only).
    motion : {"unicycle", "odometry"}

    Returns
    -------
    mu : numpy.ndarray, shape (3 + 2K,)
        New array; heading wrapped to ``[-pi, pi)``.
    sigma : numpy.ndarray, shape (3 + 2K, 3 + 2K)
        New array, symmetric.

    Raises
    ------
    ValueError
        ``mu`` not of length 3 + 2K (K >= 1), ``sigma`` not of shape (3 + 2K, 3 + 2K),
        a ``command`` not of the motion's length (2 for the unicycle, 3 for odometry),
        an unknown ``motion``, or a non-finite value.
    """
    m, s = _belief(mu, sigma)
    r = check_covariance("R", R, 3)
    if motion not in MOTIONS:
        raise ValueError(f"motion must be one of {MOTIONS}, got {motion!r}")
    theta = m[2]
    if motion == "unicycle":
        u = as_array("command", command, shape=(2,), finite=True)
        step = check_positive("dt", dt)
        dist, heading, turn = u[0] * step, theta, u[1] * step
    else:
        u = as_array("command", command, shape=(3,), finite=True)
        dist, heading, turn = u[1], theta + u[0], u[0] + u[2]
    c, sn = np.cos(heading), np.sin(heading)
    new_mu = m.copy()
    new_mu[:3] += (dist * c, dist * sn, turn)
    new_mu[2] = wrap_angle(new_mu[2])
    g = np.eye(3)
    g[0, 2], g[1, 2] = -dist * sn, dist * c
    new_sigma = s.copy()
    new_sigma[:3, :3] = g @ s[:3, :3] @ g.T + r
    new_sigma[:3, 3:] = g @ s[:3, 3:]
    new_sigma[3:, :3] = new_sigma[:3, 3:].T
    new_sigma[:3, :3] = 0.5 * (new_sigma[:3, :3] + new_sigma[:3, :3].T)
    return new_mu, new_sigma


def observation(mu, j):
    r"""Expected range and bearing of landmark(s) ``j`` and the Jacobian (Table 10.1, lines 14-21).

    With :math:`\delta = m_j - (x, y)^T` and :math:`q = \delta^T\delta`,

    .. math::

        \hat z = \begin{pmatrix} \sqrt q \\ \operatorname{wrap}(\operatorname{atan2}(\delta_y,
        \delta_x) - \theta) \end{pmatrix}, \qquad
        H = \frac{1}{q}\begin{pmatrix}
        -\sqrt q\,\delta_x & -\sqrt q\,\delta_y & 0 & \sqrt q\,\delta_x & \sqrt q\,\delta_y \\
        \delta_y & -\delta_x & -q & -\delta_y & \delta_x \end{pmatrix} F_{x,j},

    where :math:`F_{x,j}` places the five columns at the pose (0-2) and at the
    landmark (``3 + 2j``, ``4 + 2j``): every other column of the
    :math:`2 \times (3 + 2K)` Jacobian is zero.

    Parameters
    ----------
    mu : array_like, shape (3 + 2K,)
        State mean.
    j : int or array_like of int, shape (k,)
        Landmark index (or indices), ``0 <= j < K``.

    Returns
    -------
    z_hat : numpy.ndarray, shape (2,) or (k, 2)
        ``[range, bearing]``, bearing wrapped to ``[-pi, pi)``.
    H : numpy.ndarray, shape (2, 3 + 2K) or (k, 2, 3 + 2K)

    Raises
    ------
    ValueError
        A landmark estimate at the robot's position (range 0: no bearing, no Jacobian).
    """
    m = _mean(mu)
    ids = _landmark_ids("j", j, (m.size - 3) // 2)
    flat = np.atleast_1d(ids)
    z_hat, H = _observe(m, flat)
    if np.ndim(ids) == 0:
        return z_hat[0], H[0]
    return z_hat, H


def correct(mu, sigma, observations, Qt):
    r"""EKF-SLAM correction with all of one step's observations at once (Table 10.1, lines 12-25).

    The k observations ``[r, phi, j]`` (landmarks already in the map) are
    stacked into one measurement of size 2k, linearized at the predicted mean
    (the book loops over them, relinearizing after each; with one observation,
    or a linear model, the two are the same):

    .. math::

        S = H \Sigma H^T + \operatorname{diag}(Q_t, \dots, Q_t), \quad
        K = \Sigma H^T S^{-1}, \quad e = z - \hat z \ (\text{bearings wrapped}),

    .. math::

        \mu' = \mu + K e, \qquad \Sigma' = \Sigma - K S K^T ,

    the last being :math:`(I - KH)\Sigma` written so that it is symmetric by
    construction (symmetrized once more against rounding). A bearing measured
    as 3.1 rad and predicted as -3.1 rad differ by 0.08 rad, not 6.2.

    Parameters
    ----------
    mu : array_like, shape (3 + 2K,)
    sigma : array_like, shape (3 + 2K, 3 + 2K)
    observations : array_like, shape (k, 3)
        Rows ``[range, bearing, id]``; ``k`` may be 0 (or ``None``): nothing changes.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance of one ``[range, bearing]`` (positive definite).

    Returns
    -------
    mu, sigma : numpy.ndarray
        New arrays; heading wrapped, ``sigma`` symmetric.

    Raises
    ------
    ValueError
        ``observations`` not of shape (k, 3), a landmark id outside ``0 <= id < K``,
        ``Qt`` not positive definite, or shapes of ``mu`` and ``sigma`` that do not
        fit.
    """
    m, s = _belief(mu, sigma)
    obs = _observations(observations, (m.size - 3) // 2)
    qt = check_covariance("Qt", Qt, 2, definite=True)
    if len(obs) == 0:
        return m.copy(), s.copy()
    z_hat, H = _observe(m, obs[:, 2].astype(np.intp))
    k = len(obs)
    e = obs[:, :2] - z_hat
    e[:, 1] = wrap_angle(e[:, 1])
    H = H.reshape(2 * k, -1)
    hs = H @ s  # (2k, n)
    S = hs @ H.T + np.kron(np.eye(k), qt)
    gain = np.linalg.solve(S, hs).T  # K = Sigma H^T S^-1 (S and Sigma symmetric)
    new_mu = m + gain @ e.reshape(-1)
    new_mu[2] = wrap_angle(new_mu[2])
    new_sigma = s - gain @ S @ gain.T
    return new_mu, 0.5 * (new_sigma + new_sigma.T)


def add_landmark(mu, sigma, z, j, Qt):
    r"""Put landmark ``j`` into the map at its first sighting (Table 10.1, lines 10-11).

    The mean inverts the measurement model:
    :math:`m_j = (x + r\cos(\theta + \phi),\ y + r\sin(\theta + \phi))`.
    The covariance is the book's initialization with an infinite prior, in the
    limit, i.e. the linearized propagation of the pose's and the measurement's
    uncertainty, with :math:`G_x = \partial m_j / \partial x` (2 x 3) and
    :math:`G_z = \partial m_j / \partial z` (2 x 2):

    .. math::

        \Sigma_{jj} = G_x \Sigma_{xx} G_x^T + G_z Q_t G_z^T, \qquad
        \Sigma_{j\,\cdot} = G_x \Sigma_{x\,\cdot} \quad (\text{the pose's rows: every other
        entry}),

    and :math:`\Sigma_{\cdot\,j} = \Sigma_{j\,\cdot}^T`. Whatever rows and columns
    ``j`` held before are replaced. Cost O(K).

    Parameters
    ----------
    mu : array_like, shape (3 + 2K,)
    sigma : array_like, shape (3 + 2K, 3 + 2K)
    z : array_like, shape (2,)
        The first observation ``[range, bearing]`` of landmark ``j`` (range >= 0).
    j : int
        Landmark index, ``0 <= j < K``.
    Qt : array_like, shape (2, 2)
        Measurement noise covariance.

    Returns
    -------
    mu, sigma : numpy.ndarray
        New arrays with landmark ``j`` filled in.

    Raises
    ------
    ValueError
        A ``z`` not of length 2 or with a negative range, ``j`` outside
        ``0 <= j < K``, or shapes of ``mu`` and ``sigma`` that do not fit.
    """
    m, s = _belief(mu, sigma)
    jj = int(_landmark_ids("j", j, (m.size - 3) // 2, scalar=True))
    zz = as_array("z", z, shape=(2,), finite=True)
    if zz[0] < 0:
        raise ValueError(f"z's range must be >= 0, got {zz[0]}")
    qt = check_covariance("Qt", Qt, 2)
    r, angle = zz[0], m[2] + zz[1]
    c, sn = np.cos(angle), np.sin(angle)
    gx = np.array([[1.0, 0.0, -r * sn], [0.0, 1.0, r * c]])
    gz = np.array([[c, -r * sn], [sn, r * c]])
    cols = slice(3 + 2 * jj, 5 + 2 * jj)
    new_mu = m.copy()
    new_mu[cols] = m[0] + r * c, m[1] + r * sn
    new_sigma = s.copy()
    cross = gx @ s[:3]  # (2, n): the new landmark's covariance with every entry
    new_sigma[cols] = cross
    new_sigma[:, cols] = cross.T
    block = gx @ s[:3, :3] @ gx.T + gz @ qt @ gz.T
    new_sigma[cols, cols] = 0.5 * (block + block.T)
    return new_mu, new_sigma


def ekf_slam(robot_or_run, R=None, Qt=None, history=False):
    r"""Run EKF-SLAM over a whole run (Probabilistic Robotics Table 10.1).

    ::

        mu = (x0, 0, ..., 0); Sigma = 0       # the start pose defines the map's frame
        for each step:
            mu, Sigma = predict(mu, Sigma, command, R, dt, motion)
            mu, Sigma = correct(mu, Sigma, <observations of landmarks already in the map>, Qt)
            for each observation of a new landmark: mu, Sigma = add_landmark(mu, Sigma, z, j, Qt)

    A landmark seen twice in the step of its first sighting: the first row adds
    it, the others correct with it afterwards.

    Two kinds of run:

    - the fiducial robot (a :class:`robolab.fiducials.FiducialRobot`, driven from
      its current step, or a recorded :class:`robolab.fiducials.FiducialRun` or
      ``.npz`` path, replayed from its start): unicycle commands ``(v, omega)``
      with the robot's ``dt``, start at the robot's ``x0``, noise default the
      robot's own (``robot.Q``, ``robot.Qt``);
    - a :class:`robolab.datasets.FreiburgData` run: odometry ``(r1, t, r2)``
      (``motion="odometry"``), start at the origin, observation ids replaced by
      landmark rows (``data.indexed_observations(i)``); the data carries no
      noise model, so ``R`` and ``Qt`` must be given.

    Parameters
    ----------
    robot_or_run : FiducialRobot, FiducialRun, path or FreiburgData
    R : array_like, shape (3, 3), optional
        Motion noise covariance in the pose's coordinates.
    Qt : array_like, shape (2, 2), optional
        Measurement noise covariance.
    history : bool
        Also return the mean and covariance after every step.

    Returns
    -------
    dict
        ``path`` (T + 1, 3) pose estimates (row 0 is the start); ``landmarks`` (K, 2)
        and ``landmark_covs`` (K, 2, 2), NaN for a landmark never observed;
        ``observed`` (K,) bool; ``mu`` (3 + 2K,) and ``sigma`` the final belief;
        with ``history=True`` also ``means`` (T + 1, 3 + 2K) and ``covs``
        (T + 1, 3 + 2K, 3 + 2K).
    """
    steps, x0, k, r, qt = _steps(robot_or_run, R, Qt)
    mu = np.zeros(3 + 2 * k)
    mu[:3] = x0
    sigma = np.zeros((3 + 2 * k, 3 + 2 * k))
    seen = np.zeros(k, dtype=bool)
    means, covs = [mu], [sigma]
    for command, dt, motion, z in steps:
        mu, sigma = predict(mu, sigma, command, r, dt, motion)
        mu, sigma = _observe_step(mu, sigma, z, seen, qt)
        means.append(mu)
        if history:
            covs.append(sigma)
    return _report(means, covs if history else None, sigma, seen)


def _steps(robot_or_run, R, Qt):
    """``(steps, x0, K, R, Qt)``: ``steps`` yields ``(command, dt, motion, observations)``."""
    from robolab.datasets.freiburg import FreiburgData

    if isinstance(robot_or_run, FreiburgData):
        data = robot_or_run
        if R is None or Qt is None:
            raise ValueError("a FreiburgData run carries no noise model: give R and Qt")
        steps = (
            (u, 1.0, "odometry", data.indexed_observations(i))
            for i, u in enumerate(data.odometry)
        )
        x0, k = np.zeros(3), len(data.landmark_ids)
    else:
        robot = as_robot(robot_or_run)
        R = robot.Q if R is None else R
        Qt = robot.Qt if Qt is None else Qt

        def drive():
            while robot.run():
                yield robot.input(), robot.dt, "unicycle", robot.measurement()

        steps, x0, k = drive(), robot.x0, robot.n_fiducials
    return steps, x0, k, check_covariance("R", R, 3), check_covariance("Qt", Qt, 2, definite=True)


def _observe_step(mu, sigma, z, seen, qt):
    """Correct with the landmarks in the map, then add the new ones (``seen`` is updated)."""
    z = np.asarray(z, dtype=float).reshape(-1, 3)
    ids = z[:, 2].astype(np.intp)
    known = seen[ids]
    mu, sigma = correct(mu, sigma, z[known], qt)
    new = np.flatnonzero(~known)
    _, first = np.unique(ids[new], return_index=True)
    for row in new[first]:  # the observations of this step: the only loop
        mu, sigma = add_landmark(mu, sigma, z[row, :2], int(ids[row]), qt)
    again = np.setdiff1d(new, new[first])
    if again.size:
        mu, sigma = correct(mu, sigma, z[again], qt)
    seen[ids] = True
    return np.asarray(mu, dtype=float), np.asarray(sigma, dtype=float)


def _report(means, covs, sigma, seen) -> dict:
    """The result dict of :func:`ekf_slam` (and of the real-data runs)."""
    means = np.array(means)
    mu = means[-1]
    k = seen.size
    landmarks = mu[3:].reshape(k, 2).copy()
    idx = 3 + 2 * np.arange(k)[:, None] + np.arange(2)
    landmark_covs = sigma[idx[:, :, None], idx[:, None, :]]
    landmarks[~seen] = np.nan
    landmark_covs[~seen] = np.nan
    out = {
        "path": means[:, :3].copy(),
        "landmarks": landmarks,
        "landmark_covs": landmark_covs,
        "observed": seen.copy(),
        "mu": mu.copy(),
        "sigma": np.array(sigma, dtype=float),
    }
    if covs is not None:
        out["means"] = means
        out["covs"] = np.array(covs)
    return out


def _observe(m: np.ndarray, ids: np.ndarray):
    """``z_hat`` (k, 2) and ``H`` (k, 2, n) on checked arrays."""
    n = m.size
    lm = m[3:].reshape(-1, 2)[ids]
    dx, dy = lm[:, 0] - m[0], lm[:, 1] - m[1]
    q = dx * dx + dy * dy
    if np.any(q == 0):
        bad = ids[q == 0].tolist()
        raise ValueError(f"landmark(s) {bad} are estimated at the robot's position: range 0 has "
                         "no bearing and no Jacobian")
    d = np.sqrt(q)
    z_hat = np.column_stack([d, wrap_angle(np.arctan2(dy, dx) - m[2])])
    H = np.zeros((len(ids), 2, n))
    rows = np.arange(len(ids))
    H[:, 0, 0], H[:, 0, 1] = -dx / d, -dy / d
    H[:, 1, 0], H[:, 1, 1], H[:, 1, 2] = dy / q, -dx / q, -1.0
    col = 3 + 2 * ids
    H[rows, 0, col], H[rows, 0, col + 1] = dx / d, dy / d
    H[rows, 1, col], H[rows, 1, col + 1] = -dy / q, dx / q
    return z_hat, H


def _mean(mu) -> np.ndarray:
    m = as_array("mu", mu, ndim=1, finite=True)
    if m.size < 5 or m.size % 2 == 0:
        raise ValueError(
            f"mu must have shape (3 + 2K,) with K >= 1 landmarks, got {m.shape}"
        )
    return m


def _belief(mu, sigma) -> tuple[np.ndarray, np.ndarray]:
    """Checked ``mu`` and ``sigma``: shapes, finite, symmetric (O(n^2): no eigenvalues)."""
    m = _mean(mu)
    n = m.size
    s = as_array("sigma", sigma, shape=(n, n), finite=True)
    if np.abs(s - s.T).max() > 1e-9 * max(1.0, np.abs(s).max()):
        raise ValueError("sigma must be symmetric")
    if np.any(np.diag(s) < 0):
        raise ValueError(f"sigma's diagonal (variances) must be >= 0, got {np.diag(s).min()}")
    return m, s


def _landmark_ids(name, j, k, scalar=False):
    """``j`` as an int (or int array) of landmark indices in ``[0, k)``."""
    if isinstance(j, (bool, np.bool_)):
        raise TypeError(f"{name} must be a landmark index (int), got a bool")
    arr = np.asarray(j)
    if scalar and arr.ndim != 0:
        raise ValueError(f"{name} must be one landmark index, got shape {arr.shape}")
    if arr.ndim > 1 or arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be an int or a 1-D array of ints, got {j!r}")
    if np.any(arr != np.round(arr)) or np.any(arr < 0) or np.any(arr >= k):
        raise ValueError(f"{name} must hold landmark indices in [0, {k}), got {arr.tolist()}")
    return arr.astype(np.intp)


def _observations(observations, k) -> np.ndarray:
    return as_observations("observations", observations, k)
