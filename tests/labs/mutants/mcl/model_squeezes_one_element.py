"""Squeezes its result: one particle gets a log-likelihood of shape () instead of (1,).

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.geometry import compose
from robolab.validation import as_array, as_poses
from solutions.mcl import _mixture, _model_table, _params, _scan_arrays, _used_beams


def likelihood_field_model(scan, particles, field, params):
    p = as_poses("particles", particles)
    ranges, angles, _, rmax = _scan_arrays(scan)
    prm = _params(params)
    z_hit, z_rand = _mixture(prm)
    laser = as_array("params['laser_pose']", prm["laser_pose"], shape=(3,), finite=True)
    table, geometry = _model_table(field, z_hit, z_rand, rmax)
    use = _used_beams(ranges, scan, prm)
    if not use.any():
        return np.squeeze(np.zeros(p.shape[0]))
    lp = compose(p, laser)
    uv = geometry.world_to_map(lp[:, :2]).astype(np.float32) + np.float32(1.0)
    phi = lp[:, 2] - geometry.origin[2]
    c = np.cos(phi).astype(np.float32)[:, None]
    s = np.sin(phi).astype(np.float32)[:, None]
    r, a = (ranges[use], angles[use])
    qx = (r * np.cos(a) / geometry.resolution).astype(np.float32)
    qy = (r * np.sin(a) / geometry.resolution).astype(np.float32)
    u = c * qx
    u -= s * qy
    u += uv[:, 0:1]
    v = s * qx
    v += c * qy
    v += uv[:, 1:2]
    rows, cols = table.shape
    np.clip(u, 0, cols - 1, out=u)
    np.clip(v, 0, rows - 1, out=v)
    index = v.astype(np.int32)
    index *= np.int32(cols)
    index += u.astype(np.int32)
    return np.squeeze(table.ravel().take(index).sum(axis=1, dtype=np.float64))
