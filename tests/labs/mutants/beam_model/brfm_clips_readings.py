"""Clips readings into [0, max_range] instead of refusing those outside.

class: refusal
"""

import numpy as np

from solutions.beam_model import (
    _check_expected,
    _check_params,
    _check_scan_shapes,
    _log_mixture,
    _out,
    _ranges,
    p_hit,
    p_max,
    p_rand,
    p_short,
)


def beam_range_finder_model(z, z_star, params, log=False):
    prm = _check_params(params)
    zmax = prm["max_range"]
    z = _ranges("z", z)
    z_star = _ranges("z_star", z_star)
    _check_scan_shapes(z, z_star)
    z = np.clip(z, 0.0, zmax)
    _check_expected(z_star, zmax)
    z, z_star = np.broadcast_arrays(z, z_star)
    p = (
        prm["z_hit"] * p_hit(z, z_star, zmax, prm["sigma_hit"])
        + prm["z_short"] * p_short(z, z_star, prm["lambda_short"])
        + prm["z_max"] * p_max(z, zmax)
        + prm["z_rand"] * p_rand(z, zmax)
    )
    if not log:
        return _out(np.prod(p, axis=-1))
    with np.errstate(divide="ignore"):
        log_p = np.log(p)
    tiny = p < 1e-280
    if tiny.any():
        log_p[tiny] = _log_mixture(z[tiny], z_star[tiny], prm)
    return _out(log_p.sum(axis=-1))
