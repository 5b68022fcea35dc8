"""For log=True returns the log of the sum of the beams' densities, not the sum of their logs.

class: self-consistency
"""

import numpy as np

from solutions.beam_model import (
    _check_expected,
    _check_params,
    _check_scan_shapes,
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
    if np.any((z < 0) | (z > zmax)):
        raise ValueError("z must lie in [0, max_range]")
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
    return _out(np.log(p.sum(axis=-1)))
