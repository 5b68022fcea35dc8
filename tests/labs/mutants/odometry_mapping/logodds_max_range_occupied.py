# ruff: noqa: F841, E501 -- a student mistake leaves a variable unused; lines as the student wrote them
"""A max-range reading marks the cells at z_max occupied (the z_k < z_max condition of Table 9.2 is
missing).

Boundary values of a validity interval.

class: boundary
"""

import numpy as np

from robolab.geometry import wrap_angle
from solutions.odometry_mapping import (
    _beam_kinds,
    _check_grid,
    _layer,
    _pose,
    _scan_arrays,
    _sensor_model_params,
)


def logodds_update(logodds, scan, pose, grid, inverse_sensor_model_params):
    grid = _check_grid(grid)
    out = _layer("logodds", logodds, grid)
    ranges, angles, rmin, rmax = _scan_arrays(scan)
    laser = _pose("pose", pose)
    p = _sensor_model_params(inverse_sensor_model_params, grid.resolution)
    hit, no_return = _beam_kinds(ranges, rmin, rmax)
    used = hit | no_return
    if not np.any(used):
        return out
    z = np.where(hit, ranges, rmax)[used]
    beam_angles = wrap_angle(angles[used])
    order = np.argsort(beam_angles, kind="stable")
    beam_angles, z, can_hit = np.atleast_1d(beam_angles[order]), z[order], hit[used][order]

    # the cells that can be in the perceptual field: a disc of radius z_max + alpha/2
    reach = min(rmax, float(z.max()) + p["alpha"] / 2) / grid.resolution + 1.0
    centre = grid.world_to_map(laser[:2])  # (col, row), rotation-invariant disc
    lo = np.maximum(np.floor(centre - reach).astype(int), 0)
    hi = np.minimum(np.ceil(centre + reach).astype(int), [grid.shape[1], grid.shape[0]])
    if np.any(hi <= lo):
        return out
    # cell centres, separably: x = ox + cos(yaw) u - sin(yaw) v, y = oy + sin(yaw) u + cos(yaw) v
    u = ((np.arange(lo[0], hi[0]) + 0.5) * grid.resolution)[None, :]
    v = ((np.arange(lo[1], hi[1]) + 0.5) * grid.resolution)[:, None]
    c, s = np.cos(grid.origin[2]), np.sin(grid.origin[2])
    dx = (grid.origin[0] - laser[0]) + c * u - s * v
    dy = (grid.origin[1] - laser[1]) + s * u + c * v
    r = np.hypot(dx, dy)
    phi = wrap_angle(np.arctan2(dy, dx) - laser[2])

    # nearest beam in bearing, on the circle: the sorted angles padded by one beam
    # on each side (shifted by 2 pi) so that both neighbours of phi are at hand
    n = beam_angles.size
    padded = np.concatenate(
        [beam_angles[-1:] - 2 * np.pi, beam_angles, beam_angles[:1] + 2 * np.pi]
    )
    i = np.searchsorted(beam_angles, phi)  # padded[i] <= phi < padded[i + 1]
    d_left = phi - padded[i]
    d_right = padded[i + 1] - phi
    k = np.where(d_left <= d_right, (i - 1) % n, i % n)
    dphi = np.minimum(d_left, d_right)
    zk = z[k]

    in_field = (r <= np.minimum(rmax, zk + p["alpha"] / 2)) & (dphi <= p["beta"] / 2)
    occupied = in_field & (np.abs(r - zk) < p["alpha"] / 2)
    free = in_field & ~occupied & (r <= zk)
    delta = np.where(occupied, p["l_occ"] - p["l_0"], np.where(free, p["l_free"] - p["l_0"], 0.0))
    out[lo[1] : hi[1], lo[0] : hi[0]] += delta
    return out
