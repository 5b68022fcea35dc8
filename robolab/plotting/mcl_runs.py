"""Lab 05's filter runners: the notebook's MCL functions driven over the localization bag.

The notebook's exercise functions (``init_uniform``, ``mcl_step``, ...) are passed
in as arguments, so the notebook holds no hidden state and no long helper code:

* :func:`load_localization` -- map, scans, odometry and ground truth at the scan stamps;
* :func:`run_mcl` -- MCL over the bag with a step function (AMCL's update
  thresholds and resample interval handled as AMCL's node does);
* :func:`run_augmented` -- augmented MCL (recovery), optionally with a kidnapping;
* :func:`run_kld` -- MCL with KLD-sampling (adaptive particle count);
* :func:`estimate_pose` -- the best hypothesis (heaviest cluster), as AMCL publishes.

The figures of their results are in :mod:`robolab.plotting.mcl`, which re-exports these.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from robolab.geometry import angle_diff, compose, relative, wrap_angle
from robolab.maps import OccupancyGrid, load_map
from robolab.progress import progress_bar
from robolab.validation import as_array, as_poses, check_positive

__all__ = [
    "SNAPSHOT_TIMES",
    "CLUSTER_BIN",
    "KLD_BIN_SIZE",
    "LocalizationData",
    "load_localization",
    "estimate_pose",
    "pose_errors",
    "convergence_time",
    "run_mcl",
    "run_augmented",
    "kld_resample",
    "run_kld",
]

#: The snapshot times of lab 05's figures, seconds since the first scan.
SNAPSHOT_TIMES = (5.0, 10.0, 14.0, 20.0, 30.0, 42.0, 60.0, 75.0)
#: Cluster size of :func:`estimate_pose`, metres.
CLUSTER_BIN = 0.5


@dataclass(frozen=True, eq=False)
class LocalizationData:
    """The localization bag at the scan stamps, as arrays.

    Attributes
    ----------
    grid : OccupancyGrid
        ``data/office.yaml``.
    t : ndarray (T,)
        Scan stamps, seconds since the first scan.
    ranges : ndarray (T, B)
        Raw ranges (inf, NaN and range_max kept).
    angles : ndarray (B,)
        Beam angles in the laser frame.
    range_min, range_max : float
    odom : ndarray (T, 3)
        Odometry ``odom -> base_link`` interpolated at each scan stamp.
    truth : ndarray (T, 3)
        Ground truth ``map -> base_link`` at each scan stamp.
    laser_pose : ndarray (3,)
        ``base_link -> base_laser_link``.
    """

    grid: OccupancyGrid
    t: np.ndarray
    ranges: np.ndarray
    angles: np.ndarray
    range_min: float
    range_max: float
    odom: np.ndarray
    truth: np.ndarray
    laser_pose: np.ndarray

    def __len__(self) -> int:
        return self.t.size

    def scan(self, i: int) -> dict:
        """Scan ``i`` as the plain dict the exercise functions take."""
        return {
            "ranges": self.ranges[i],
            "angles": self.angles,
            "range_min": self.range_min,
            "range_max": self.range_max,
        }

    def index_at(self, t: float) -> int:
        """Index of the last scan at or before ``t`` seconds."""
        return int(np.clip(np.searchsorted(self.t, t + 1e-9, side="right") - 1, 0, len(self) - 1))


#: AMCL's default KLD histogram bins: 0.5 m in x and y, 10 degrees in heading.
KLD_BIN_SIZE = (0.5, 0.5, math.radians(10.0))
#: :func:`kld_resample` bins this many draws (or ``4 * n_min``) first, and 4x more while the
#: bound is not met: a converged belief stops at about ``n_min``.
KLD_FIRST_DRAWS = 1024


def load_localization(
    bag_path=None,
    map_path=None,
    *,
    scan_topic: str = "/base_scan",
    odom="/odom",
    truth="/ground_truth",
    base_frame: str = "base_link",
    truth_delay: float = 0.0,
    scan_delay: float = 0.0,
) -> LocalizationData:
    """Read ``data/localization.bag`` and ``data/office.yaml`` (or the given files).

    Odometry and truth are interpolated at the scan stamps (``PoseTrack.at``); the
    laser mount comes from ``/tf`` (``laser_pose_in_base``). The topics and message
    types are configurable (:func:`robolab.datasets.rosbag.read_recording`): ``odom``
    and ``truth`` are an Odometry or PoseStamped topic or ``("/tf", parent, child)``.
    The real Olin Neato bag loads with ``scan_topic="/scan", truth="/map_pose"``;
    ``truth_delay`` and ``scan_delay`` are :func:`~robolab.datasets.rosbag.read_recording`'s.
    """
    from robolab import DATA_DIR
    from robolab.datasets.rosbag import read_recording

    bag_path = Path(bag_path) if bag_path is not None else DATA_DIR / "localization.bag"
    map_path = Path(map_path) if map_path is not None else DATA_DIR / "office.yaml"
    grid = load_map(map_path)
    rec = read_recording(
        bag_path,
        scan_topic=scan_topic,
        odom=odom,
        truth=truth,
        base_frame=base_frame,
        truth_delay=truth_delay,
        scan_delay=scan_delay,
    )
    if rec.truth is None:
        raise ValueError("load_localization needs a ground-truth source (truth=None given)")
    stamps = rec.scans.stamps
    return LocalizationData(
        grid=grid,
        t=stamps - stamps[0],
        ranges=np.asarray(rec.scans.ranges, dtype=float),
        angles=np.asarray(rec.scans.angles, dtype=float),
        range_min=float(rec.scans.range_min),
        range_max=float(rec.scans.range_max),
        odom=rec.odom,
        truth=rec.truth,
        laser_pose=rec.laser_pose,
    )


# ----------------------------------------------------------------------------------------------
# estimates and errors
# ----------------------------------------------------------------------------------------------
def estimate_pose(particles, weights=None, bin_size: float = CLUSTER_BIN) -> np.ndarray:
    """The best hypothesis: weighted mean of the heaviest cluster of particles.

    Particles are binned on a ``bin_size`` grid in (x, y); the bin whose 3 x 3
    neighbourhood holds the most weight is the best hypothesis, and the
    estimate is the weighted mean position (circular mean heading) of the
    particles in that neighbourhood. A plain weighted mean would land between
    the modes of a multimodal belief (four identical offices); AMCL publishes
    the mean of its heaviest cluster for the same reason.

    Returns
    -------
    numpy.ndarray, shape (3,)
    """
    p = as_poses("particles", particles)
    w = (
        np.full(len(p), 1.0 / len(p))
        if weights is None
        else as_array("weights", weights, shape=(len(p),), finite=True, nonnegative=True)
    )
    size = check_positive("bin_size", bin_size)
    # per column (contiguous) rather than (N, 2) reductions along axis 0: the same
    # integers, half the time; this runs after every step of every run of lab 05
    i = np.floor(p[:, 0] / size).astype(np.int64)
    j = np.floor(p[:, 1] / size).astype(np.int64)
    i -= i.min()
    j -= j.min()
    shape = (int(i.max()) + 1, int(j.max()) + 1)
    cell = i * shape[1]
    cell += j
    # np.bincount adds in the order of np.add.at (the same sums), without its per-call cost
    hist = np.bincount(cell, weights=w, minlength=shape[0] * shape[1])
    score = ndimage.uniform_filter(hist.reshape(shape), size=3, mode="constant")
    bi, bj = divmod(int(np.argmax(score)), shape[1])
    # the particles of the best bin's 3 x 3 neighbourhood, in their order: a mask of bins
    chosen = np.zeros(shape, dtype=bool)
    chosen[max(bi - 1, 0) : bi + 2, max(bj - 1, 0) : bj + 2] = True
    near = np.flatnonzero(chosen.ravel()[cell])
    if len(near) == len(p):  # a converged cloud: all of it, no gathers
        pn, wn = p, w
    else:
        pn, wn = p.take(near, axis=0), w.take(near)
    total = wn.sum()
    if not total > 0:
        wn, total = np.ones(len(near)), float(len(near))
    # np.average's arithmetic (product, sum, divide by the weights' sum), without its checks;
    # x and y summed row after row as numpy sums an (n, 2) array along axis 0 (the earlier
    # code; a pairwise sum of each column would round differently)
    x, y = (_sum_in_order(pn[:, c] * wn) / total for c in (0, 1))
    th = pn[:, 2]
    th = math.atan2((np.sin(th) * wn).sum() / total, (np.cos(th) * wn).sum() / total)
    return np.array([x, y, wrap_angle(th)])


def _sum_in_order(a: np.ndarray):
    """``a[0] + a[1] + ...`` left to right (float64; 0 for no terms)."""
    return np.add.accumulate(a)[-1] if len(a) else np.float64(0.0)


def pose_errors(estimates, truth) -> tuple[np.ndarray, np.ndarray]:
    """Position error (m) and absolute heading error (rad) of ``(T, 3)`` estimates vs truth."""
    e = as_poses("estimates", estimates)
    g = as_poses("truth", truth)
    if e.shape != g.shape:
        raise ValueError(
            f"estimates and truth must have the same shape, got {e.shape} and {g.shape}"
        )
    return np.hypot(*(e[:, :2] - g[:, :2]).T), np.abs(angle_diff(e[:, 2], g[:, 2]))


# ----------------------------------------------------------------------------------------------
# runners
# ----------------------------------------------------------------------------------------------
def convergence_time(result: dict, tolerance: float = 0.5) -> float | None:
    """The time from which a run's position error stays below ``tolerance`` metres.

    Parameters
    ----------
    result : dict
        A run of :func:`run_mcl`, :func:`run_kld` or :func:`run_augmented` (``t`` and
        ``position_error``, one per update).
    tolerance : float
        Position error in metres that counts as locked on.

    Returns
    -------
    float or None
        The first update time ``t[k]`` with ``position_error[k:] < tolerance``; None when
        the last update is still off.
    """
    check_positive("tolerance", tolerance)
    t = np.asarray(result["t"], dtype=float)
    err = np.asarray(result["position_error"], dtype=float)
    if t.shape != err.shape or t.ndim != 1:
        raise ValueError(f"result['t'] and result['position_error'] must be (T,), got "
                         f"{t.shape} and {err.shape}")
    bad = np.flatnonzero(~(err < tolerance))
    if len(bad) == 0:
        return float(t[0]) if len(t) else None
    if bad[-1] == len(t) - 1:
        return None
    return float(t[bad[-1] + 1])


def _run_result(data: LocalizationData, idx, est, particles, weights, **extra) -> dict:
    """What every runner returns: times, estimates against truth, errors, the final particles."""
    est = np.asarray(est)
    pos, head = pose_errors(est, data.truth[idx])
    return {
        "t": data.t[idx],
        "estimate": est,
        "truth": data.truth[idx],
        "position_error": pos,
        "heading_error": head,
        "particles": particles,
        "weights": weights,
        **extra,
    }


def _snapshot_indices(data: LocalizationData, times: Sequence[float]) -> dict[int, float]:
    return {data.index_at(t): float(t) for t in times if t <= data.t[-1] + 1e-9}


def run_mcl(
    data: LocalizationData,
    mcl_step: Callable,
    particles,
    field,
    params: dict,
    rng: np.random.Generator,
    *,
    every: int = 1,
    t_start: float = 0.0,
    t_end: float | None = None,
    snapshot_times: Sequence[float] = SNAPSHOT_TIMES,
    progress: bool = True,
    desc: str = "MCL",
) -> dict:
    """Run ``mcl_step`` over the bag, as AMCL's node drives its filter.

    The run starts at the scan at ``t_start`` (seconds). Its first scan always
    updates (``force_update``); after that the step is
    called on every ``every``-th scan with ``odom_prev`` = the odometry of the
    last *update*, so motions below AMCL's thresholds accumulate; the number of
    updates so far goes in as ``params["update_count"]``.

    Returns
    -------
    dict
        ``t`` (T,), ``estimate`` (T, 3) (:func:`estimate_pose` after each
        processed scan), ``truth`` (T, 3), ``position_error`` and
        ``heading_error`` (T,), ``snapshots``: {time: (particles, weights)},
        ``particles``, ``weights`` at the end, ``updates`` (int).
    """
    p = as_poses("particles", particles)
    w = np.full(len(p), 1.0 / len(p))
    end = len(data) if t_end is None else data.index_at(t_end) + 1
    idx = np.arange(data.index_at(t_start), end, int(every))
    snaps = _snapshot_indices(data, snapshot_times)
    odom_prev = data.odom[idx[0]]
    updates = 0
    est, snapshots = [], {}
    bar = progress_bar(idx, desc=desc, unit="scan", disable=not progress, leave=False)
    for k, i in enumerate(bar):
        prm = {
            **params,
            "laser_pose": data.laser_pose,
            "update_count": updates,
            "force_update": k == 0,
        }
        p, w, updated = mcl_step(p, w, odom_prev, data.odom[i], data.scan(i), field, prm, rng)
        p, w = np.asarray(p, dtype=float), np.asarray(w, dtype=float)
        if updated:
            odom_prev = data.odom[i]
            updates += 1
        est.append(estimate_pose(p, w))
        for j in [j for j in snaps if j <= i and snaps[j] not in snapshots]:
            snapshots[snaps[j]] = (p.copy(), w.copy())
    return _run_result(
        data,
        idx,
        est,
        p,
        w,
        snapshots=snapshots,
        updates=updates,
    )


def run_augmented(
    data: LocalizationData,
    augmented_mcl_step: Callable,
    particles,
    field,
    params: dict,
    rng: np.random.Generator,
    *,
    kidnap_at: float | None = None,
    kidnap_to=None,
    every: int = 2,
    t_end: float | None = None,
    progress: bool = True,
    desc: str = "augmented MCL",
) -> dict:
    """Run augmented MCL over the bag, optionally kidnapping the robot.

    A kidnapping at ``kidnap_at`` seconds moves every particle rigidly so that
    the filter believes the robot is at ``kidnap_to`` (a confidently wrong
    pose) while the data go on from the true pose: the same as carrying the
    robot away without telling the filter.

    Returns
    -------
    dict
        As :func:`run_mcl`, plus ``w_slow``, ``w_fast`` (T,) and
        ``random_fraction`` (T,) = ``max(0, 1 - w_fast / w_slow)``.
    """
    p = as_poses("particles", particles)
    w = np.full(len(p), 1.0 / len(p))
    end = len(data) if t_end is None else data.index_at(t_end) + 1
    idx = np.arange(0, end, int(every))
    w_slow = w_fast = 0.0
    est, slow, fast = [], [], []
    kidnapped = kidnap_at is None
    for i in progress_bar(idx, desc=desc, unit="scan", disable=not progress, leave=False):
        if not kidnapped and data.t[i] >= kidnap_at:
            # move the whole cloud rigidly so that the current estimate lands on kidnap_to
            target = as_array("kidnap_to", kidnap_to, shape=(3,), finite=True)
            p = compose(target, relative(estimate_pose(p, w), p))
            kidnapped = True
        prev = data.odom[max(i - int(every), 0)]
        prm = {**params, "laser_pose": data.laser_pose}
        p, w, w_slow, w_fast = augmented_mcl_step(
            p, w, prev, data.odom[i], data.scan(i), field, prm, rng, data.grid, w_slow, w_fast
        )
        p, w = np.asarray(p, dtype=float), np.asarray(w, dtype=float)
        est.append(estimate_pose(p, w))
        slow.append(w_slow)
        fast.append(w_fast)
    slow, fast = np.array(slow), np.array(fast)
    return _run_result(
        data,
        idx,
        est,
        p,
        w,
        w_slow=slow,
        w_fast=fast,
        random_fraction=np.clip(1.0 - fast / np.where(slow > 0, slow, 1.0), 0.0, 1.0),
    )


def kld_resample(
    particles,
    weights,
    rng,
    kld_sample_size: Callable,
    *,
    epsilon: float = 0.05,
    z: float = 2.326,
    bin_size=KLD_BIN_SIZE,
    n_min: int = 100,
    n_max: int = 5000,
) -> np.ndarray:
    """KLD-sampling (Table 8.4), vectorized: draw until the bound for the occupied bins is met.

    ``n_max`` particles are drawn i.i.d. from the weights (as AMCL's
    ``pf_update_resample`` draws them one by one); ``k_j`` is the number of
    distinct (x, y, theta) bins among the first ``j`` draws, and the set is cut
    at the first ``j >= max(n_min, kld_sample_size(k_j, epsilon, z))``
    (AMCL's bins are 0.5 m, 0.5 m, 10 degrees).

    Returns
    -------
    numpy.ndarray, shape (n, 3)
        The new particle set; its size ``n`` adapts to the belief's spread.
    """
    p = as_poses("particles", particles)
    w = as_array("weights", weights, shape=(len(p),), finite=True, nonnegative=True)
    prob = w / w.sum()
    n_max = int(n_max)
    # rng.choice(len(p), size=n_max, p=prob) in its two parts: its checks of prob (the same
    # errors; size 0 draws nothing, and no particles keep n_max for choice's own error)
    # and its sampling (n_max uniforms looked up in the normalized cdf), the same random
    # stream; only the prefix of draws that the cut can keep is looked up and binned,
    # growing 4x at a time (the cut is often n_min of 5000): 3.2x faster in lab 05
    rng.choice(len(p), size=0 if len(p) else n_max, p=prob)
    cdf = prob.cumsum()
    cdf /= cdf[-1]
    uniform = rng.random(n_max)
    bins = np.asarray(bin_size, dtype=float)
    m = min(n_max, max(4 * int(n_min), KLD_FIRST_DRAWS))
    while True:
        draws = p[cdf.searchsorted(uniform[:m], side="right")]
        # the first draw of each bin within the first m draws: the same as within all
        first = _first_of_each_row(np.floor(draws / bins).astype(np.int64))
        new_bin = np.zeros(m, dtype=np.int64)
        new_bin[first] = 1
        k = np.cumsum(new_bin)
        need = np.maximum(np.asarray(kld_sample_size(k, epsilon, z), dtype=float), n_min)
        done = np.flatnonzero(np.arange(1, m + 1) >= need)
        if done.size:
            return draws[: int(done[0]) + 1]
        if m == n_max:
            return draws
        m = min(n_max, 4 * m)


def _first_of_each_row(cells: np.ndarray) -> np.ndarray:
    """Index of the first occurrence of each distinct row of an (N, D) integer array.

    ``np.unique(cells, axis=0, return_index=True)[1]``, as a set of indices: each row
    becomes one integer (mixed radix over the columns' spans) and the 1-D unique
    sorts integers instead of rows (``axis=0`` sorts a structured view, ten times
    slower; this runs after every step of the KLD run). Rows whose spans would not fit
    an int64 go the ``axis=0`` way.
    """
    lo = cells.min(axis=0)
    span = cells.max(axis=0) - lo + 1
    if float(np.prod(span.astype(float))) >= 2.0**62:
        return np.unique(cells, axis=0, return_index=True)[1]
    key = np.zeros(len(cells), dtype=np.int64)
    for column, size in zip((cells - lo).T, span, strict=True):
        key *= size
        key += column
    return np.unique(key, return_index=True)[1]


def run_kld(
    data: LocalizationData,
    mcl_step: Callable,
    kld_sample_size: Callable,
    particles,
    field,
    params: dict,
    rng: np.random.Generator,
    *,
    epsilon: float = 0.05,
    z: float = 2.326,
    n_min: int = 200,
    n_max: int = 5000,
    every: int = 2,
    t_end: float | None = None,
    progress: bool = True,
    desc: str = "MCL with KLD-sampling",
) -> dict:
    """MCL with KLD-sampling: ``mcl_step`` predicts and weights, :func:`kld_resample` resamples.

    ``mcl_step`` is called with ``resample_interval`` larger than the run, so it
    never resamples itself.

    Returns
    -------
    dict
        As :func:`run_mcl` plus ``n_particles`` (T,): the particles each update used
        (the first is the initial set's size).
    """
    p = as_poses("particles", particles)
    w = np.full(len(p), 1.0 / len(p))
    end = len(data) if t_end is None else data.index_at(t_end) + 1
    idx = np.arange(0, end, int(every))
    est, counts = [], []
    for i in progress_bar(idx, desc=desc, unit="scan", disable=not progress, leave=False):
        prev = data.odom[max(i - int(every), 0)]
        prm = {
            **params,
            "laser_pose": data.laser_pose,
            "resample_interval": 10**9,
            "update_count": 0,
            "force_update": True,
        }
        p, w, _ = mcl_step(p, w, prev, data.odom[i], data.scan(i), field, prm, rng)
        p, w = np.asarray(p, dtype=float), np.asarray(w, dtype=float)
        est.append(estimate_pose(p, w))
        counts.append(len(p))  # the particles this update used
        p = kld_resample(p, w, rng, kld_sample_size, epsilon=epsilon, z=z, n_min=n_min, n_max=n_max)
        w = np.full(len(p), 1.0 / len(p))
    return _run_result(
        data,
        idx,
        est,
        p,
        w,
        n_particles=np.array(counts),
    )
