"""Lab 04 on real data: occupancy grid mapping of a CARMEN log (the Intel Research Lab).

The corrected log carries, with every scan, the laser's corrected pose; its ``ODOM``
messages are the raw wheel odometry. Mapping with both shows what lab 04 shows on
the simulated bag: raw odometry smears the map, corrected poses give sharp walls.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robolab.datasets.carmen import CarmenLog
from robolab.geometry import anchor_odometry
from robolab.maps import OccupancyGrid, from_logodds
from robolab.validation import check_count, check_positive

__all__ = ["carmen_poses", "map_carmen"]


def carmen_poses(log: CarmenLog, source: str = "corrected", laser: str | None = None) -> np.ndarray:
    """The laser poses of every scan: ``"corrected"`` (the log's) or raw ``"odometry"``.

    Raw odometry is interpolated at the scan stamps and anchored at the first
    corrected pose (:func:`robolab.geometry.anchor_odometry`), so both paths start
    at the same pose.
    """
    scans = log.laser(laser)
    if scans.laser_poses is None:
        raise ValueError(f"{log.path}: these scans carry no poses to map with")
    if source == "corrected":
        return scans.laser_poses.copy()
    if source == "odometry":
        if log.odometry is None:
            raise ValueError(f"{log.path}: the log has no ODOM messages")
        return anchor_odometry(log.odometry.at(scans.scans.stamps), scans.laser_poses[0])
    raise ValueError(f"source must be 'corrected' or 'odometry', got {source!r}")


def map_carmen(
    log: CarmenLog,
    logodds_update: Callable,
    params: dict,
    *,
    poses=None,
    resolution: float = 0.1,
    range_cap: float = 30.0,
    every: int = 1,
    start: int = 0,
    margin: float = 2.0,
    laser: str | None = None,
) -> OccupancyGrid:
    """Map a CARMEN log's scans with the lab's ``logodds_update``.

    Parameters
    ----------
    log : CarmenLog
    logodds_update : callable
        ``logodds_update(logodds, scan, laser_pose, grid, params)`` (lab 04).
    params : dict
        Its inverse sensor model parameters (e.g. ``alpha`` of two cells).
    poses : array_like, shape (T, 3), optional
        The laser poses; default :func:`carmen_poses` ``(log, "corrected")``.
    resolution : float
        Cell size, metres.
    range_cap : float
        Readings at or beyond this many metres count as no return up to it (the
        Intel laser's 81.83 m no-return readings would otherwise clear the whole map).
    every : int
        Use every ``every``-th scan, from scan ``start`` on.
    laser : str, optional
        The laser message type (default FLASER or ROBOTLASER1).
    margin : float
        Metres of map around the bounding box of the poses and the hits.

    Returns
    -------
    OccupancyGrid
        Never-observed cells unknown (:func:`robolab.maps.from_logodds`).
    """
    scans = log.laser(laser).scans
    p = carmen_poses(log, "corrected", laser) if poses is None else np.asarray(poses, float)
    if p.shape != (len(scans), 3):
        raise ValueError(f"poses must have shape ({len(scans)}, 3), got {p.shape}")
    res = check_positive("resolution", resolution)
    cap = min(check_positive("range_cap", range_cap), scans.range_max)
    step = check_count("every", every)
    first = check_count("start", start, minimum=0)
    idx = np.arange(first, len(scans), step)
    if idx.size == 0:
        raise ValueError(f"start={start} leaves no scan (the log has {len(scans)})")
    hits = scans.valid[idx] & (scans.ranges[idx] < cap)
    a = p[idx, 2:3] + scans.angles[None, :]
    r = np.where(hits, scans.ranges[idx], 0.0)
    ex = np.where(hits, p[idx, 0:1] + r * np.cos(a), p[idx, 0:1])
    ey = np.where(hits, p[idx, 1:2] + r * np.sin(a), p[idx, 1:2])
    m = check_positive("margin", margin, allow_zero=True)
    lo = np.array([ex.min(), ey.min()]) - m
    hi = np.array([ex.max(), ey.max()]) + m
    shape = tuple(np.ceil((hi - lo)[::-1] / res).astype(int))
    grid = OccupancyGrid(np.zeros(shape), res, np.array([lo[0], lo[1], 0.0]))
    logodds = np.zeros(shape)
    observed = np.zeros(shape, dtype=bool)
    for i in idx:
        ranges = np.where(scans.ranges[i] >= cap, np.inf, scans.ranges[i])
        scan = {
            "ranges": ranges,
            "angles": scans.angles,
            "range_min": scans.range_min,
            "range_max": cap,
        }
        new = logodds_update(logodds, scan, p[i], grid, params)
        observed |= new != logodds
        logodds = new
    return from_logodds(logodds, grid, prior=float(params.get("l_0", 0.0)), observed=observed)
