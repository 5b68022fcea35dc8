# ruff: noqa: F841, E501 -- a student mistake leaves a variable unused; lines as the student wrote them
"""With z_rand = 0 the log is taken of the Gaussian itself, which underflows to log(0) = -inf far
from obstacles.

Numerics of the log form (a mixture component is zero).

class: underflow
"""

import math

import numpy as np

from robolab.geometry import compose
from robolab.maps import OccupancyGrid
from robolab.validation import as_array, as_poses
from solutions.mcl import _gaussian, _mixture, _params, _scan_arrays, _used_beams


def likelihood_field_model(scan, particles, field, params):
    p = as_poses("particles", particles)
    ranges, angles, _, rmax = _scan_arrays(scan)
    dist = np.asarray(field["distance"], dtype=float)
    sigma, dmax = float(field["sigma_hit"]), float(field["max_dist"])
    geometry = OccupancyGrid(np.zeros((1, 1)), field["resolution"], field["origin"])
    prm = _params(params)
    z_hit, z_rand = _mixture(prm)
    laser = as_array("params['laser_pose']", prm["laser_pose"], shape=(3,), finite=True)
    use = _used_beams(ranges, scan, prm)
    if not use.any():
        return np.zeros(p.shape[0])
    # per-cell log mixture, with a one-cell border scored as d = max_dist (off the map)
    log_hit = math.log(z_hit) if z_hit > 0 else -np.inf
    padded = np.pad(dist, 1, constant_values=dmax)
    if z_rand > 0:  # log(z_hit N(d) + z_rand / z_max), never log(0)
        table = np.log(z_hit * _gaussian(padded, sigma) + z_rand / rmax)
    else:
        table = np.log(z_hit * _gaussian(padded, sigma))
    table = table.astype(np.float32)  # half the memory for the random-access gather below
    # Endpoints in continuous map coordinates (cells). world_to_map is affine, so the
    # laser's map coordinates plus each beam rotated by (heading - map yaw) / resolution
    # equal world_to_map of the endpoint; float32 halves the memory traffic.
    lp = compose(p, laser)
    uv = geometry.world_to_map(lp[:, :2]).astype(np.float32) + np.float32(1.0)  # +1: the border
    phi = lp[:, 2] - geometry.origin[2]
    c = np.cos(phi).astype(np.float32)[:, None]
    s = np.sin(phi).astype(np.float32)[:, None]
    r, a = ranges[use], angles[use]
    qx = (r * np.cos(a) / geometry.resolution).astype(np.float32)
    qy = (r * np.sin(a) / geometry.resolution).astype(np.float32)
    u = c * qx
    u -= s * qy
    u += uv[:, 0:1]
    v = s * qx
    v += c * qy
    v += uv[:, 1:2]
    rows, cols = table.shape
    # clip into the border (which holds the off-map score); floor == truncation for u >= 0
    np.clip(u, 0, cols - 1, out=u)
    np.clip(v, 0, rows - 1, out=v)
    index = v.astype(np.int32)
    index *= np.int32(cols)
    index += u.astype(np.int32)
    return table.ravel().take(index).sum(axis=1, dtype=np.float64)
