"""An endpoint off the map is scored as if it were on an obstacle (d = 0) instead of d = max_dist.

Empty or partially known maps (endpoints off the map).

class: empty-map
"""

import math

import numpy as np

from robolab.geometry import compose
from robolab.validation import as_array, as_poses
from solutions.mcl import (
    _field_arrays,
    _gaussian,
    _log_gaussian,
    _mixture,
    _params,
    _scan_arrays,
    _used_beams,
)


def likelihood_field_model(scan, particles, field, params):
    r"""Log-likelihood :math:`\log p(z \mid x, m)` of a scan for every particle: Table 6.3.

    Each valid beam :math:`k` (range :math:`z^k`, angle :math:`\theta_k` in the
    laser frame) is projected from the laser's pose
    :math:`x_{laser} = x \oplus x_{laser}^{base}` (``params["laser_pose"]``):

    .. math::

        x_{z^k} = x_{laser} + z^k \cos(\theta_{laser} + \theta_k), \quad
        y_{z^k} = y_{laser} + z^k \sin(\theta_{laser} + \theta_k),

    looked up in the field (world -> cell with the map's resolution and origin,
    seed 004's detail 1), and scored with the mixture

    .. math::

        \log p(z \mid x, m) = \sum_k \log\Big( z_{hit}\, \mathcal N(d(x_{z^k}); 0, \sigma_{hit}^2)
                                             + \frac{z_{rand}}{z_{max}} \Big)

    with :math:`z_{max}` the scan's ``range_max``. Beams that are not real
    returns (NaN, inf, outside ``[range_min, range_max)``: max-range readings
    carry no position information, AMCL skips them) are skipped. An endpoint
    outside the map is scored as if at :math:`d_{max}` (seed 004's detail 2,
    AMCL's ``max_occ_dist``): the smallest per-beam likelihood, a penalty that
    stays finite. ``params["max_beams"]`` keeps every ``(B - 1) // (max_beams - 1)``-th
    beam as AMCL does. The mixture is summed in log space, so the result is
    finite even for ``z_rand = 0``.

    Parameters
    ----------
    scan : dict
        ``"ranges"`` (B,), ``"angles"`` (B,) radians, ``"range_min"``, ``"range_max"`` metres.
    particles : array_like, shape (N, 3)
    field : dict
        From :func:`likelihood_field` (uses ``distance``, ``resolution``,
        ``origin``, ``sigma_hit``, ``max_dist``).
    params : dict
        ``z_hit``, ``z_rand`` (>= 0, not both 0), optional ``laser_pose`` (3,)
        and ``max_beams``; see :data:`DEFAULT_PARAMS`.

    Returns
    -------
    numpy.ndarray, shape (N,)
        Log-likelihoods (natural log); 0 for every particle if no beam is valid.
        Use :func:`normalize_log_weights` to turn them into weights.
    """
    p = as_poses("particles", particles)
    ranges, angles, _, rmax = _scan_arrays(scan)
    dist, sigma, dmax, geometry = _field_arrays(field)
    prm = _params(params)
    z_hit, z_rand = _mixture(prm)
    laser = as_array("params['laser_pose']", prm["laser_pose"], shape=(3,), finite=True)
    use = _used_beams(ranges, scan, prm)
    if not use.any():
        return np.zeros(p.shape[0])
    # per-cell log mixture, with a one-cell border scored as d = max_dist (off the map)
    log_hit = math.log(z_hit) if z_hit > 0 else -np.inf
    padded = np.pad(dist, 1, constant_values=0.0)
    if z_rand > 0:  # log(z_hit N(d) + z_rand / z_max), never log(0)
        table = np.log(z_hit * _gaussian(padded, sigma) + z_rand / rmax)
    else:
        table = log_hit + _log_gaussian(padded, sigma)
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
