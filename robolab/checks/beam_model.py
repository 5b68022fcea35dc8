"""Visible checks for lab 02, the beam model (``notebooks/02_beam_model.ipynb``).

Quick and friendly: a worked value, the shape, one invariant (a density
integrates to 1). The hidden tests check much more (several parameters, the
point mass, a loop oracle, underflow, the maze, bad input).
"""

from __future__ import annotations

import math

import numpy as np

from robolab.checks.base import (
    CheckFailed,
    check,
    expect_close,
    expect_raises,
    expect_shape,
    where_wrong,
)

__all__ = [
    "check_p_hit",
    "check_p_short",
    "check_p_max",
    "check_p_rand",
    "check_beam_range_finder_model",
    "check_pose_likelihood_map",
]

#: The parameters the checks use (the notebook's defaults).
PARAMS = {
    "z_hit": 0.8,
    "z_short": 0.1,
    "z_max": 0.05,
    "z_rand": 0.05,
    "sigma_hit": 0.2,
    "lambda_short": 0.5,
    "max_range": 5.0,
}


def _expect_integral(name, total, expected=1.0, tol=1e-4):
    if not abs(total - expected) < tol:
        raise CheckFailed(f"{name} integrates to {total:.6f}, expected {expected:g}")


@check
def check_p_hit(p_hit):
    """A worked value, zero outside [0, z_max], and the integral over [0, z_max] is 1."""
    # z* = 1, sigma = 0.5, z_max = 5: eta = 1 / (Phi(8) - Phi(-2)) = 1.0233...
    eta = 1.0 / (0.5 * (math.erf(8 / math.sqrt(2)) - math.erf(-2 / math.sqrt(2))))
    expect_close(
        "p_hit(1.0, z_star=1.0, z_max=5.0, sigma_hit=0.5)",
        p_hit(1.0, 1.0, 5.0, 0.5),
        eta / (0.5 * math.sqrt(2 * math.pi)),
        rtol=1e-6,
    )
    got = expect_shape(
        "p_hit(z (4,), z_star=1.0, ...)",
        p_hit(np.array([-1.0, 0.5, 1.0, 6.0]), 1.0, 5.0, 0.5),
        (4,),
    )
    if got[0] != 0 or got[3] != 0:
        raise CheckFailed("p_hit must be 0 for readings outside [0, z_max]")
    # z* = 0.2 near the lower end: the Gaussian is cut at 0 and eta restores the lost mass
    z = np.linspace(0.0, 5.0, 20001)
    f = expect_shape("p_hit(z (20001,), z_star=0.2, ...)", p_hit(z, 0.2, 5.0, 0.5), z.shape)
    eta = 1.0 / (0.5 * (math.erf(4.8 / 0.5 / math.sqrt(2)) - math.erf(-0.2 / 0.5 / math.sqrt(2))))
    expected = eta * np.exp(-0.5 * ((z - 0.2) / 0.5) ** 2) / (0.5 * math.sqrt(2 * math.pi))
    wrong = where_wrong(
        z,
        f,
        expected,
        {"0": 0.0, "z_max": 5.0},
        "the Gaussian is cut at 0, so eta must restore the lost mass (use the normal CDF)",
    )
    if wrong is not None:
        raise CheckFailed(f"p_hit(z, z_star=0.2, z_max=5, sigma_hit=0.5) on [0, 5]: {wrong}")
    _expect_integral(
        "p_hit(z, z_star=0.2, z_max=5, sigma_hit=0.5) over [0, 5]", float(np.trapezoid(f, z))
    )


@check
def check_p_short(p_short):
    """A worked value, zero beyond z*, and the integral over [0, z*] is 1."""
    # lambda = 0.5, z* = 2: eta = 1 / (1 - e^-1); p_short(1) = eta * 0.5 * e^-0.5
    expect_close(
        "p_short(1.0, z_star=2.0, lambda_short=0.5)",
        p_short(1.0, 2.0, 0.5),
        0.5 * math.exp(-0.5) / (1 - math.exp(-1.0)),
        rtol=1e-6,
    )
    got = expect_shape(
        "p_short(z (3,), z_star=2.0, ...)", p_short(np.array([0.0, 2.5, -1.0]), 2.0, 0.5), (3,)
    )
    if got[1] != 0 or got[2] != 0:
        raise CheckFailed("p_short must be 0 for readings beyond z_star (or negative)")
    z = np.linspace(0.0, 3.0, 20001)
    f = expect_shape("p_short(z (20001,), z_star=3, ...)", p_short(z, 3.0, 0.8), z.shape)
    wrong = where_wrong(
        z,
        f,
        0.8 * np.exp(-0.8 * z) / (1.0 - math.exp(-2.4)),
        {"0": 0.0, "z_star": 3.0},
        "eta = 1 / (1 - exp(-lambda_short * z_star))",
    )
    if wrong is not None:
        raise CheckFailed(f"p_short(z, z_star=3, lambda_short=0.8) on [0, 3]: {wrong}")
    _expect_integral(
        "p_short(z, z_star=3, lambda_short=0.8) over [0, 3]", float(np.trapezoid(f, z))
    )
    at_zero = np.asarray(p_short(np.array([0.0, 1.0]), 0.0, 0.5), dtype=float)
    if not np.all(np.isfinite(at_zero)):
        raise CheckFailed(
            f"p_short(z, z_star=0, ...) returned {at_zero}: handle z_star = 0 without dividing by 0"
        )


@check
def check_p_max(p_max):
    """1 at exactly z_max, 0 just below it and elsewhere."""
    got = expect_shape(
        "p_max(z (4,), z_max=5.0)", p_max(np.array([0.0, 4.999, 5.0, 6.0]), 5.0), (4,)
    )
    expect_close("p_max([0, 4.999, 5, 6], z_max=5)", got, [0.0, 0.0, 1.0, 0.0])


@check
def check_p_rand(p_rand):
    """1/z_max on [0, z_max), 0 at z_max and outside."""
    got = expect_shape(
        "p_rand(z (4,), z_max=5.0)", p_rand(np.array([-0.1, 0.0, 2.5, 5.0]), 5.0), (4,)
    )
    expect_close("p_rand([-0.1, 0, 2.5, 5], z_max=5)", got, [0.0, 0.2, 0.2, 0.0])


@check
def check_beam_range_finder_model(beam_range_finder_model):
    """One beam by hand, q for many poses, q = exp(log q), and no underflow in log form."""
    prm = PARAMS
    # One beam at z = z* = 2:
    # z_hit * eta / (sigma sqrt(2 pi)) + z_short * p_short(2 | 2) + z_rand / z_max.
    eta_hit = 1.0 / (0.5 * (math.erf(15 / math.sqrt(2)) - math.erf(-10 / math.sqrt(2))))
    expected = (
        0.8 * eta_hit / (0.2 * math.sqrt(2 * math.pi))
        + 0.1 * 0.5 * math.exp(-1.0) / (1 - math.exp(-1.0))
        + 0.05 / 5.0
    )
    expect_close(
        "beam_range_finder_model([2.0], [2.0], params)",
        beam_range_finder_model(np.array([2.0]), np.array([2.0]), prm),
        expected,
        rtol=1e-6,
    )
    rng = np.random.default_rng(0)
    z_star = rng.uniform(0.5, 4.5, (5, 8))
    z = np.clip(z_star[0] + rng.normal(0, 0.1, 8), 0, 5)
    q = expect_shape(
        "beam_range_finder_model(z (8,), z_star (5, 8), params)",
        beam_range_finder_model(z, z_star, prm),
        (5,),
    )
    log_q = expect_shape(
        "beam_range_finder_model(..., log=True)",
        beam_range_finder_model(z, z_star, prm, log=True),
        (5,),
    )
    expect_close("exp(log q) versus q", np.exp(log_q), q, rtol=1e-8, atol=0)
    many = float(
        np.asarray(beam_range_finder_model(np.full(2000, 1.0), np.full(2000, 3.0), prm, log=True))
    )
    if not np.isfinite(many):
        raise CheckFailed(
            "log=True gave -inf for 2000 beams: sum the logs of the beams, "
            "do not take the log of the (underflowed) product"
        )
    expect_raises(
        "beam_range_finder_model with a reading of 6 m beyond max_range = 5 m",
        ValueError,
        beam_range_finder_model,
        np.array([1.0, 6.0]),
        np.array([1.0, 2.0]),
        prm,
    )
    expect_raises(
        "beam_range_finder_model with weights summing to 1.2",
        ValueError,
        beam_range_finder_model,
        np.array([1.0]),
        np.array([1.0]),
        dict(prm, z_hit=prm["z_hit"] + 0.2),
    )


@check
def check_pose_likelihood_map(pose_likelihood_map):
    """A 10 m x 10 m box: the (P, H) shape, and the centre beats a corner position."""
    from robolab.maps import OccupancyGrid
    from robolab.raycast import cast_rays

    data = np.zeros((100, 100))
    data[[0, -1], :] = 1.0
    data[:, [0, -1]] = 1.0
    data[30:40, 60:70] = 1.0  # a pillar breaks the symmetry
    box = OccupancyGrid(data, 0.1)
    angles = np.linspace(-np.pi, np.pi, 16, endpoint=False)
    truth = np.array([3.05, 5.05, 0.0])
    scan = cast_rays(box, truth, angles, PARAMS["max_range"])[0]
    positions = np.array([[3.05, 5.05], [8.05, 8.05], [5.05, 2.05]])
    headings = np.array([np.pi / 2, 0.0])
    log_l = expect_shape(
        "pose_likelihood_map(scan (16,), ..., positions (3, 2), headings (2,))",
        pose_likelihood_map(scan, box, angles, PARAMS, positions, headings),
        (3, 2),
    )
    if np.unravel_index(int(np.argmax(log_l)), log_l.shape) != (0, 1):
        raise CheckFailed(
            f"the scan was taken at (3.05, 5.05) heading 0, but your map is highest "
            f"elsewhere:\n{log_l}"
        )
