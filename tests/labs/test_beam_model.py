"""Hidden tests for lab 02, the beam model (seed 001; Probabilistic Robotics Table 6.1). 100 points.

Every test calls only ``lab.<exercise>(...)`` with plain data (arrays, floats,
dicts, the maze's OccupancyGrid) and compares results after
``np.asarray(..., dtype=float)``, so it works on the reference solution and,
with ``--notebook``, across the grader's process boundary. Densities are
evaluated on a whole grid of readings in one call (one round trip).

Oracles:
* normalization: composite Simpson / trapezoid rules on fine grids whose nodes
  include every breakpoint of the integrand (0, z*, z_max), so the only error
  is the rule's own (bounded in each test's comment);
* reference values from the book's formulas written here with ``math.erf``
  (the normalizer) and ``math.exp``;
* a plain per-beam Python loop version of Table 6.1 (:func:`_loop_model`);
* ray casting with :func:`robolab.raycast.cast_rays` on the bundled maze.

Stochastic inputs come from fixed seeds; tolerances state their reason.

Points: p_hit 14, p_short 12, p_max 6, p_rand 8, beam_range_finder_model 40,
pose_likelihood_map 20. Refusal and end-to-end tests pay only when the
exercise's value tests pass (``requires``); the model's failures point to the
component densities when those fail their own tests (``USES``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import simpson
from scipy.special import ndtr

from robolab.checks.base import where_wrong
from robolab.maps import load_maze
from robolab.raycast import cast_rays

grades = pytest.mark.grades
requires = pytest.mark.requires

COMPONENTS = ["p_hit", "p_short", "p_max", "p_rand"]
#: CPU seconds the reference solution's worker uses while graded (loading and every call,
#: children included: `cpu_seconds` of the correct example in `make grade`'s gradebook.json,
#: 2026-12-02): a submission gets 8 times that in total, at least 20 s (docs/grading.md).
REFERENCE_CPU_SECONDS = 1.0

#: A student's model calls their own component densities; the map calls their model.
USES = {
    "beam_range_finder_model": COMPONENTS,
    "pose_likelihood_map": ["beam_range_finder_model", *COMPONENTS],
}

PARAMS = {
    "z_hit": 0.7,
    "z_short": 0.15,
    "z_max": 0.05,
    "z_rand": 0.1,
    "sigma_hit": 0.2,
    "lambda_short": 0.8,
    "max_range": 5.0,
}


def _f(x):
    return np.asarray(x, dtype=float)


def _below(x):
    """The largest float below ``x``."""
    return float(np.nextafter(x, -np.inf))


def _ref_p_hit(z, z_star, z_max, sigma):
    """Book eq. 6.4-6.6 for one reading; eta through the error function."""
    if not 0.0 <= z <= z_max:
        return 0.0
    cdf = lambda x: 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))  # noqa: E731
    eta = 1.0 / (cdf((z_max - z_star) / sigma) - cdf(-z_star / sigma))
    return eta * math.exp(-0.5 * ((z - z_star) / sigma) ** 2) / (sigma * math.sqrt(2.0 * math.pi))


def _ref_p_short(z, z_star, lam):
    if z_star <= 0.0 or not 0.0 <= z <= z_star:
        return 0.0
    return lam * math.exp(-lam * z) / (1.0 - math.exp(-lam * z_star))


def _ref_p_hit_grid(z, z_star, z_max, sigma):
    """:func:`_ref_p_hit` on an array of readings (the same formula, through ``ndtr``)."""
    eta = 1.0 / (ndtr((z_max - z_star) / sigma) - ndtr(-z_star / sigma))
    inside = (z >= 0.0) & (z <= z_max)
    return np.where(inside, eta * np.exp(-0.5 * ((z - z_star) / sigma) ** 2), 0.0) / (
        sigma * math.sqrt(2.0 * math.pi)
    )


def _ref_p_short_grid(z, z_star, lam):
    """:func:`_ref_p_short` on an array of readings (z* > 0)."""
    inside = (z >= 0.0) & (z <= z_star)
    return np.where(inside, lam * np.exp(-lam * z) / -math.expm1(-lam * z_star), 0.0)


def _loop_model(z, z_star, prm):
    """Table 6.1 as a plain loop over beams: returns (q, sum of log p)."""
    zmax = prm["max_range"]
    q, log_q = 1.0, 0.0
    for zk, zsk in zip(z, z_star, strict=True):
        p = (
            prm["z_hit"] * _ref_p_hit(zk, zsk, zmax, prm["sigma_hit"])
            + prm["z_short"] * _ref_p_short(zk, zsk, prm["lambda_short"])
            + prm["z_max"] * (1.0 if zk == zmax else 0.0)
            + prm["z_rand"] * (1.0 / zmax if 0.0 <= zk < zmax else 0.0)
        )
        q *= p
        log_q += math.log(p)
    return q, log_q


def _random_scan(rng, n, b, zmax, max_fraction=0.1):
    """Expected ranges in [0, zmax] (some zmax) and readings around them (some max, some short)."""
    z_star = rng.uniform(0.05, zmax, (n, b))
    z_star[rng.random((n, b)) < 0.1] = zmax
    z = np.clip(z_star + rng.normal(0.0, 0.3, (n, b)), 0.0, zmax)
    short = rng.random((n, b)) < 0.15
    z[short] = rng.uniform(0.0, 1.0, short.sum()) * z_star[short]
    z[rng.random((n, b)) < max_fraction] = zmax
    return z, z_star


# ================================ p_hit (14) ================================
@grades("p_hit", points=1)  # per case: 5 points
@pytest.mark.parametrize(
    "z_star, z_max, sigma",
    [(2.0, 5.0, 0.2), (0.0, 5.0, 0.5), (4.9, 5.0, 0.3), (10.0, 10.0, 1.0), (0.3, 8.0, 4.0)],
)
def test_p_hit_integrates_to_one(lab, z_star, z_max, sigma):
    """p_hit integrates to 1 over [0, z_max], also when z* is at or near an end (truncation)."""
    # Simpson on 200001 nodes: h = z_max / 2e5 <= 5e-5 m and sigma >= 0.2, so the
    # rule's error (h^4 f'''' z_max / 180) is below 1e-12.
    z = np.linspace(0.0, z_max, 200001)
    f = _f(lab.p_hit(z, z_star, z_max, sigma))
    assert f.shape == z.shape, (
        f"p_hit of {z.size} readings: expected shape {z.shape}, got {f.shape}"
    )
    wrong = where_wrong(
        z,
        f,
        _ref_p_hit_grid(z, z_star, z_max, sigma),
        {"0": 0.0, "z_max": z_max, "z*": z_star},
        "eta must be 1 / (Phi((z_max - z*) / sigma) - Phi(-z* / sigma)), the Gaussian's mass "
        "inside [0, z_max]",
    )
    assert wrong is None, (
        f"p_hit with z* = {z_star}, z_max = {z_max}, sigma = {sigma} on {z.size} readings of "
        f"[0, z_max]: {wrong}"
    )
    total = simpson(f, x=z)
    assert total == pytest.approx(1.0, abs=1e-8), (
        f"p_hit with z* = {z_star}, z_max = {z_max}, sigma = {sigma}: expected the integral "
        f"over [0, z_max] to be 1, got {total:.8f}: eta must be 1 / (Phi((z_max - z*) / sigma) "
        "- Phi(-z* / sigma)), the Gaussian's mass inside [0, z_max]"
    )


@grades("p_hit", points=4)
def test_p_hit_reference_values_and_broadcasting(lab):
    """p_hit matches eta N(z; z*, sigma^2) with eta from the normal CDF, and broadcasts.

    One reading in an array, the smallest input, gives an array of one density.
    """
    one = _f(lab.p_hit(np.array([1.0]), 1.0, 5.0, 0.4))
    assert one.shape == (1,), f"p_hit(z = [1.0], 1, 5, 0.4): expected shape (1,), got {one.shape}"
    z = np.array([[0.0], [1.0], [2.5], [4.99], [5.0]])  # (5, 1)
    z_star = np.array([0.5, 2.5, 4.8])  # (3,)
    got = _f(lab.p_hit(z, z_star, 5.0, 0.4))
    assert got.shape == (5, 3), (
        f"z (5, 1) and z_star (3,) should broadcast to (5, 3), got {got.shape}"
    )
    expected = np.array([[_ref_p_hit(a, b, 5.0, 0.4) for b in z_star] for a in z[:, 0]])
    wrong = where_wrong(
        np.repeat(z[:, 0], 3),
        got.ravel(),
        expected.ravel(),
        {"0": 0.0, "z_max": 5.0},
        "eta must be 1 / (Phi((z_max - z*) / sigma) - Phi(-z* / sigma))",
    )
    assert wrong is None, (
        f"p_hit for z in (0, 1, 2.5, 4.99, 5) and z* in (0.5, 2.5, 4.8), z_max 5, sigma 0.4: "
        f"{wrong}"
    )
    np.testing.assert_allclose(
        got,
        expected,
        rtol=1e-9,
        atol=1e-300,
        err_msg="p_hit for z in (0, 1, 2.5, 4.99, 5) (rows; both ends of [0, z_max] included) "
        "and z* in (0.5, 2.5, 4.8) (columns), z_max 5, sigma 0.4: expected eta N(z; z*, sigma^2)",
    )
    got = float(_f(lab.p_hit(2.5, 2.5, 5.0, 2.0)))
    expected = _ref_p_hit(2.5, 2.5, 5.0, 2.0)
    assert got == pytest.approx(expected, rel=1e-9), (
        f"p_hit(2.5, 2.5, 5, sigma=2): a wide Gaussian is truncated to [0, 5], eta = "
        f"1 / (Phi(1.25) - Phi(-1.25)): expected {expected:.6g}, got {got:.6g}"
    )


@grades("p_hit", points=3)
def test_p_hit_support_and_continuity(lab):
    """p_hit is 0 outside [0, z_max], positive and continuous inside, never NaN."""
    outside = _f(lab.p_hit(np.array([-1.0, -1e-9, 5.0 + 1e-9, 7.0]), 2.0, 5.0, 0.5))
    np.testing.assert_array_equal(
        outside, 0.0, err_msg="p_hit at z = -1, -1e-9, 5 + 1e-9, 7 (outside [0, 5]): expected 0"
    )
    z = np.linspace(1e-6, 5.0 - 1e-6, 100001)
    f = _f(lab.p_hit(z, 2.0, 5.0, 0.5))
    assert np.all(np.isfinite(f)) and np.all(f > 0), (
        f"p_hit on (0, 5) with z* = 2, sigma = 0.5: expected finite positive values, got "
        f"min {np.nanmin(f):.3g} and {int(np.sum(~np.isfinite(f)))} non-finite"
    )
    # |f'| <= eta * max N' = eta / (sigma^2 sqrt(2 pi e)) < 1.1 per metre: neighbours
    # h = 5e-5 m apart differ by less than 1e-4.
    jump = float(np.max(np.abs(np.diff(f))))
    assert jump < 1e-4, (
        f"p_hit on 100001 points of (0, 5): expected a continuous density (steps below 1e-4), "
        f"got a jump of {jump:.3g}"
    )
    far = _f(lab.p_hit(np.array([0.0, 5.0]), 2.5, 5.0, 0.01))
    assert np.all(np.isfinite(far)) and np.all(far >= 0), (
        f"p_hit 250 sigma from z* (z = 0 and 5, z* = 2.5, sigma = 0.01): expected tiny but "
        f"finite values, got {far}"
    )


@grades("p_hit", points=2)
@requires("test_p_hit_reference_values_and_broadcasting")
def test_p_hit_rejects_bad_input(lab, refuses):
    """p_hit: sigma <= 0, z* beyond z_max or negative, shapes that do not broadcast: ValueError."""
    with refuses(ValueError, "sigma_hit = -0.1 (a standard deviation must be > 0)"):
        lab.p_hit(1.0, 1.0, 5.0, -0.1)
    with refuses(ValueError, "sigma_hit = 0 (a standard deviation must be > 0)"):
        lab.p_hit(1.0, 1.0, 5.0, 0.0)
    with refuses(ValueError, "z_star = 6 beyond z_max = 5"):
        lab.p_hit(1.0, 6.0, 5.0, 0.1)
    with refuses(ValueError, "z_star = -0.5, a negative expected range"):
        lab.p_hit(1.0, -0.5, 5.0, 0.1)
    with refuses(ValueError, "z of shape (3,) and z_star of shape (4,), which do not broadcast"):
        lab.p_hit(np.ones(3), np.ones(4), 5.0, 0.1)


# ================================ p_short (12) ================================
@grades("p_short", points=1)  # per case: 4 points
@pytest.mark.parametrize("z_star, lam", [(2.0, 0.5), (4.0, 3.0), (0.1, 0.01), (8.0, 20.0)])
def test_p_short_integrates_to_one(lab, z_star, lam):
    """p_short integrates to 1 over [0, z*] (the exponential's eta) and is 0 beyond z*."""
    # Simpson on 200001 nodes of [0, z*]: error <= h^4 lam^5 z* / 180 < 1e-9 for these values.
    z = np.linspace(0.0, z_star, 200001)
    f = _f(lab.p_short(z, z_star, lam))
    assert f.shape == z.shape, (
        f"p_short of {z.size} readings: expected shape {z.shape}, got {f.shape}"
    )
    wrong = where_wrong(
        z,
        f,
        _ref_p_short_grid(z, z_star, lam),
        {"0": 0.0, "z*": z_star},
        "eta must be 1 / (1 - exp(-lambda z*)), the exponential's mass inside [0, z*]",
    )
    assert wrong is None, (
        f"p_short with z* = {z_star}, lambda = {lam} on {z.size} readings of [0, z*]: {wrong}"
    )
    total = simpson(f, x=z)
    assert total == pytest.approx(1.0, abs=1e-7), (
        f"p_short with z* = {z_star}, lambda = {lam}: expected the integral over [0, z*] to be "
        f"1, got {total:.8f}: eta must be 1 / (1 - exp(-lambda z*))"
    )
    beyond = _f(lab.p_short(np.array([z_star * 1.001, z_star + 1.0, -0.1]), z_star, lam))
    np.testing.assert_array_equal(
        beyond,
        0.0,
        err_msg=f"p_short beyond z* = {z_star} (and at z = -0.1): an unexpected object is "
        "always closer than z*, expected 0",
    )


@grades("p_short", points=4)
def test_p_short_reference_values(lab):
    """p_short = lambda e^{-lambda z} / (1 - e^{-lambda z*}) on [0, z*]; decreasing; broadcasts."""
    z = np.array([[0.0], [0.5], [1.0], [2.9]])
    z_star = np.array([1.0, 3.0])
    got = _f(lab.p_short(z, z_star, 1.5))
    assert got.shape == (4, 2), f"z (4, 1) and z_star (2,): expected shape (4, 2), got {got.shape}"
    expected = np.array([[_ref_p_short(a, b, 1.5) for b in z_star] for a in z[:, 0]])
    wrong = where_wrong(
        np.repeat(z[:, 0], 2),
        got.ravel(),
        expected.ravel(),
        {"0": 0.0, "z* = 1": 1.0},
        "eta must be 1 / (1 - exp(-lambda z*))",
    )
    assert wrong is None, f"p_short for z in (0, 0.5, 1, 2.9) and z* in (1, 3), lambda 1.5: {wrong}"
    np.testing.assert_allclose(
        got,
        expected,
        rtol=1e-9,
        err_msg="p_short for z in (0, 0.5, 1, 2.9) (rows; z = z* = 1 included) and z* in "
        "(1, 3) (columns), lambda 1.5: expected lambda e^(-lambda z) / (1 - e^(-lambda z*)) "
        "on [0, z*], 0 beyond",
    )
    inside = _f(lab.p_short(np.linspace(0.0, 3.0, 50), 3.0, 1.5))
    assert np.all(np.diff(inside) < 0), (
        "p_short on [0, z*] with z* = 3, lambda = 1.5: expected a strictly decreasing density"
    )


@grades("p_short", points=2)
def test_p_short_small_and_zero_z_star(lab):
    """p_short: z* = 0 gives finite values and no short reading beyond it; tiny z* is accurate."""
    at_zero = _f(lab.p_short(np.array([0.0, 0.5, 2.0]), 0.0, 1.0))
    assert np.all(np.isfinite(at_zero)) and np.all(at_zero >= 0), (
        f"p_short(z = (0, 0.5, 2), z* = 0): expected finite, non-negative values (no 0 / 0), "
        f"got {at_zero}"
    )
    np.testing.assert_array_equal(
        at_zero[1:], 0.0, err_msg="p_short(z = 0.5 and 2, z* = 0): expected 0 beyond z*"
    )
    small = float(_f(lab.p_short(0.0, 1e-6, 2.0)))
    expected = 2.0 / -math.expm1(-2e-6)
    assert small == pytest.approx(expected, rel=1e-6), (
        f"p_short(0, z* = 1e-6, lambda = 2): expected eta lambda = 2 / (1 - e^(-2e-6)) = "
        f"{expected:.7g}, got {small:.7g}"
    )


@grades("p_short", points=2)
@requires("test_p_short_reference_values")
def test_p_short_rejects_bad_input(lab, refuses):
    """p_short: lambda_short <= 0 and a negative z* raise ValueError."""
    with refuses(ValueError, "lambda_short = 0 (the rate must be > 0)"):
        lab.p_short(1.0, 2.0, 0.0)
    with refuses(ValueError, "lambda_short = -1 (the rate must be > 0)"):
        lab.p_short(1.0, 2.0, -1.0)
    with refuses(ValueError, "z_star = -2, a negative expected range"):
        lab.p_short(1.0, -2.0, 1.0)


# ================================ p_max (6) ================================
@grades("p_max", points=4)
def test_p_max_is_a_point_mass_at_exactly_z_max(lab):
    """p_max is 1 at exactly z_max and 0 everywhere else, even 1 ulp away."""
    z = np.array([0.0, 2.0, _below(5.0), 5.0, float(np.nextafter(5.0, np.inf)), 7.0])
    np.testing.assert_array_equal(
        _f(lab.p_max(z, 5.0)),
        [0, 0, 0, 1, 0, 0],
        err_msg="p_max at z = 0, 2, 1 ulp below 5, 5, 1 ulp above 5, 7 (z_max = 5): expected 1 "
        "at exactly z_max and 0 elsewhere (no tolerance)",
    )
    grid = _f(lab.p_max(np.array([[30.0, 29.99], [0.0, 30.0]]), 30.0))
    np.testing.assert_array_equal(
        grid, [[1, 0], [0, 1]], err_msg="p_max of a (2, 2) array with z_max = 30"
    )
    got = float(_f(lab.p_max(3.5, 3.5)))
    assert got == 1.0, f"p_max(3.5, z_max = 3.5): expected 1, got {got!r}"


@grades("p_max", points=2)
@requires("test_p_max_is_a_point_mass_at_exactly_z_max")
def test_p_max_rejects_bad_input(lab, refuses):
    """p_max: a non-positive z_max raises ValueError."""
    with refuses(ValueError, "z_max = 0 (the maximum range must be > 0)"):
        lab.p_max(1.0, 0.0)
    with refuses(ValueError, "z_max = -5 (the maximum range must be > 0)"):
        lab.p_max(1.0, -5.0)


# ================================ p_rand (8) ================================
@grades("p_rand", points=5)
def test_p_rand_uniform_on_half_open_range(lab):
    """p_rand is 1/z_max on [0, z_max), 0 at z_max and outside, and integrates to 1."""
    for z_max in (1.0, 5.0, 30.0):
        z = np.linspace(0.0, _below(z_max), 10001)
        f = _f(lab.p_rand(z, z_max))
        np.testing.assert_allclose(
            f,
            1.0 / z_max,
            rtol=1e-12,
            err_msg=f"p_rand on [0, z_max) with z_max = {z_max}: expected 1 / z_max everywhere",
        )
        area = np.trapezoid(f, z)
        assert area == pytest.approx(1.0, rel=1e-12), (
            f"p_rand with z_max = {z_max}: expected the integral over [0, z_max) to be 1, "
            f"got {area!r}"
        )
        outside = _f(lab.p_rand(np.array([z_max, -0.1, z_max + 1.0]), z_max))
        np.testing.assert_array_equal(
            outside,
            0.0,
            err_msg=f"p_rand at z = z_max = {z_max}, -0.1 and z_max + 1: expected 0 "
            "([0, z_max) is half-open: a reading of z_max is p_max's)",
        )


@grades("p_rand", points=2)
def test_p_rand_keeps_the_shape_of_z(lab):
    """p_rand of a (3, 4) array of readings is a (3, 4) array."""
    got = _f(lab.p_rand(np.full((3, 4), 1.0), 2.0))
    assert got.shape == (3, 4), f"z of shape (3, 4): expected shape (3, 4), got {got.shape}"
    np.testing.assert_allclose(
        got, 0.5, err_msg="p_rand(z = 1, z_max = 2) for a (3, 4) array: expected 0.5 everywhere"
    )


@grades("p_rand", points=1)
@requires("test_p_rand_uniform_on_half_open_range")
def test_p_rand_rejects_bad_input(lab, refuses):
    """p_rand: a non-positive z_max raises ValueError."""
    with refuses(ValueError, "z_max = 0 (the maximum range must be > 0)"):
        lab.p_rand(1.0, 0.0)
    with refuses(ValueError, "z_max = -2 (the maximum range must be > 0)"):
        lab.p_rand(1.0, -2.0)


# ========================== beam_range_finder_model (40) ==========================
@grades("beam_range_finder_model", points=2)  # per case: 6 points
@pytest.mark.parametrize("z_star", [0.7, 2.5, 5.0])
def test_mixture_integrates_to_one_minus_w_max_plus_point_mass(lab, z_star):
    """One beam: the mixture integrates to 1 - w_max on [0, z_max); the point mass adds w_max."""
    zmax = PARAMS["max_range"]
    # Piecewise Simpson on [0, z*] and (z*, z_max) (p_short jumps at z*); the last
    # node is 1 ulp below z_max, so the point mass is excluded. Error < 1e-9.
    end = _below(zmax)
    pieces = [np.linspace(0.0, min(z_star, end), 100001)]
    if z_star < end:
        pieces.append(np.linspace(float(np.nextafter(z_star, np.inf)), end, 100001))
    total = 0.0
    for nodes in pieces:
        q = _f(
            lab.beam_range_finder_model(nodes[:, None], np.full((nodes.size, 1), z_star), PARAMS)
        )
        assert q.shape == (nodes.size,), (
            f"z (N, 1) with z_star (N, 1), N = {nodes.size} poses of one beam: expected shape "
            f"(N,), got {q.shape}"
        )
        total += simpson(q, x=nodes)
    assert total == pytest.approx(1.0 - PARAMS["z_max"], abs=1e-6), (
        f"one beam, z* = {z_star}: expected the mixture to integrate to 1 - w_max = "
        f"{1 - PARAMS['z_max']} over [0, z_max), got {total:.7f}"
    )
    at_max = float(_f(lab.beam_range_finder_model(np.array([zmax]), np.array([z_star]), PARAMS)))
    assert at_max >= PARAMS["z_max"] - 1e-12, (
        f"a reading of exactly max_range with z* = {z_star}: expected at least w_max = "
        f"{PARAMS['z_max']} (the point mass), got {at_max!r}"
    )


@grades("beam_range_finder_model", points=4)
def test_mixture_point_mass_at_exactly_max_range(lab):
    """A reading of exactly max_range gets the z_max weight; 1 ulp below, the z_rand density."""
    zmax = PARAMS["max_range"]
    # z* = 2 m, sigma = 0.1 m: p_hit at 5 m is 30 sigma out (< 1e-190) and p_short is 0 beyond z*.
    prm = dict(PARAMS, sigma_hit=0.1)
    z = np.array([[zmax], [_below(zmax)]])
    q = _f(lab.beam_range_finder_model(z, np.full((2, 1), 2.0), prm))
    assert q[0] == pytest.approx(prm["z_max"], rel=1e-9), (
        f"a reading of exactly max_range = 5 with z* = 2: expected w_max * p_max = "
        f"{prm['z_max']}, got {q[0]!r}"
    )
    assert q[1] == pytest.approx(prm["z_rand"] / zmax, rel=1e-9), (
        f"a reading 1 ulp below max_range with z* = 2: expected only w_rand / z_max = "
        f"{prm['z_rand'] / zmax} (no point mass), got {q[1]!r}"
    )


@grades("beam_range_finder_model", points=3)
def test_mixture_continuity_and_support(lab):
    """One beam: continuous on (0, z*) and (z*, z_max), positive on [0, z_max] when z_rand > 0."""
    z_star = 2.5
    for a, b in ((1e-6, z_star - 1e-6), (z_star + 1e-6, 5.0 - 1e-6)):
        z = np.linspace(a, b, 50001)
        q = _f(lab.beam_range_finder_model(z[:, None], np.full((z.size, 1), z_star), PARAMS))
        assert np.all(np.isfinite(q)) and np.all(q > 0), (
            f"one beam, z* = 2.5, readings in ({a:g}, {b:g}): expected positive finite values "
            f"(z_rand > 0), got min {np.nanmin(q):.3g}"
        )
        # |dq/dz| < 5 per metre and h = 5e-5 m: neighbours differ by less than 2.5e-4.
        jump = float(np.max(np.abs(np.diff(q))))
        assert jump < 2.5e-4, (
            f"one beam, z* = 2.5, readings in ({a:g}, {b:g}): expected a continuous mixture, "
            f"got a jump of {jump:.3g}"
        )
    q = _f(
        lab.beam_range_finder_model(
            np.array([[z_star], [float(np.nextafter(z_star, 9))]]), np.full((2, 1), z_star), PARAMS
        )
    )
    jump = PARAMS["z_short"] * _ref_p_short(z_star, z_star, PARAMS["lambda_short"])
    assert q[0] - q[1] == pytest.approx(jump, rel=1e-6), (
        f"at z = z* = 2.5 the short component ends: expected a drop of z_short p_short(z*) = "
        f"{jump:.6g} just past z*, got {q[0] - q[1]:.6g}"
    )


MODEL_VALUES = ("test_agrees_with_plain_loop", "test_mixture_point_mass_at_exactly_max_range")


@grades("beam_range_finder_model", points=5)
@requires(*MODEL_VALUES)
def test_product_equals_exp_of_log_form(lab):
    """q (log=False) equals exp(log q) (log=True) for one pose and for many poses."""
    rng = np.random.default_rng(202)
    z, z_star = _random_scan(rng, 20, 30, PARAMS["max_range"])
    q = _f(lab.beam_range_finder_model(z, z_star, PARAMS))
    log_q = _f(lab.beam_range_finder_model(z, z_star, PARAMS, log=True))
    assert q.shape == log_q.shape == (20,), (
        f"20 poses of 30 beams: expected shapes (20,) for q and log q, got {q.shape} and "
        f"{log_q.shape}"
    )
    # 30 beams keep q well inside the double range, so exp(log q) is accurate to ~30 ulp per beam.
    np.testing.assert_allclose(
        q,
        np.exp(log_q),
        rtol=1e-9,
        err_msg="20 random scans: expected q (log=False) to equal exp(log q) (log=True)",
    )
    one = float(_f(lab.beam_range_finder_model(z[0], z_star[0], PARAMS, log=True)))
    assert one == pytest.approx(log_q[0], rel=1e-12), (
        f"one scan (B,) alone: expected the same log q as in the batch, {log_q[0]!r}, got {one!r}"
    )


@grades("beam_range_finder_model", points=6)
def test_agrees_with_plain_loop(lab):
    """Random scans: matches a per-beam loop of Table 6.1 for (B,), (N, B) z_star and (N, B) z."""
    rng = np.random.default_rng(203)
    prm = {
        "z_hit": 0.6,
        "z_short": 0.2,
        "z_max": 0.08,
        "z_rand": 0.12,
        "sigma_hit": 0.35,
        "lambda_short": 1.3,
        "max_range": 8.0,
    }
    z, z_star = _random_scan(rng, 12, 25, prm["max_range"])
    expected = np.array([_loop_model(z[i], z_star[i], prm) for i in range(12)])
    np.testing.assert_allclose(
        _f(lab.beam_range_finder_model(z, z_star, prm)),
        expected[:, 0],
        rtol=1e-9,
        err_msg="12 random scans of 25 beams: expected q = prod_k (z_hit p_hit + z_short "
        "p_short + z_max p_max + z_rand p_rand) (Table 6.1)",
    )
    np.testing.assert_allclose(
        _f(lab.beam_range_finder_model(z, z_star, prm, log=True)),
        expected[:, 1],
        rtol=1e-9,
        err_msg="12 random scans, log=True: expected sum_k log(mixture_k)",
    )
    expected_one = np.array([_loop_model(z[0], z_star[i], prm)[1] for i in range(12)])
    got = _f(lab.beam_range_finder_model(z[0], z_star, prm, log=True))
    assert got.shape == (12,), (
        f"one scan (B,) and 12 poses (12, B): expected (12,), got {got.shape}"
    )
    np.testing.assert_allclose(
        got,
        expected_one,
        rtol=1e-9,
        err_msg="one scan (B,) against 12 poses' z* (12, B): expected one log q per pose",
    )
    single = _f(lab.beam_range_finder_model(z[3], z_star[3], prm))
    assert single.shape == () and float(single) == pytest.approx(expected[3, 0], rel=1e-9), (
        f"one scan, one pose: expected the single number {expected[3, 0]:.6g}, got {single!r}"
    )


@grades("beam_range_finder_model", points=4)
@requires(*MODEL_VALUES)
def test_log_form_does_not_underflow(lab):
    """3000 beams: the product underflows to 0.0 but the log form stays finite and exact."""
    rng = np.random.default_rng(204)
    z, z_star = _random_scan(rng, 1, 3000, PARAMS["max_range"])
    expected_log = _loop_model(z[0], z_star[0], PARAMS)[1]
    assert expected_log < -1000, "test setup: the product of 3000 beams must underflow"
    log_q = float(_f(lab.beam_range_finder_model(z[0], z_star[0], PARAMS, log=True)))
    assert np.isfinite(log_q) and log_q == pytest.approx(expected_log, rel=1e-10), (
        f"3000 beams, log=True: expected sum of the per-beam logs {expected_log:.6f}, got "
        f"{log_q!r}: take the log per beam and sum, not the log of the product"
    )
    q = float(_f(lab.beam_range_finder_model(z[0], z_star[0], PARAMS)))
    assert q == 0.0, f"3000 beams, log=False: the product underflows, expected 0.0, got {q!r}"


@grades("beam_range_finder_model", points=4)
@requires(*MODEL_VALUES)
def test_log_form_with_vanishing_components(lab):
    """log=True stays exact when z_short = z_rand = 0 and a beam is 40 sigma off (p underflows)."""
    # Only p_hit and p_max remain. z = 3, z* = 1, sigma = 0.05: u = 40, so p_hit is about
    # e^-800, below the smallest double: a per-beam log(p) is -inf although log p is -800.
    prm = dict(PARAMS, z_hit=0.9, z_short=0.0, z_max=0.1, z_rand=0.0, sigma_hit=0.05)
    z, z_star = np.array([3.0, 1.0, 5.0]), np.array([1.0, 1.0, 2.0])
    sigma = prm["sigma_hit"]
    cdf = lambda x: 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))  # noqa: E731
    log_hit = [
        math.log(0.9)
        - math.log(cdf((5.0 - zs) / sigma) - cdf(-zs / sigma))
        - math.log(sigma * math.sqrt(2.0 * math.pi))
        - 0.5 * ((zz - zs) / sigma) ** 2
        for zz, zs in ((3.0, 1.0), (1.0, 1.0))
    ]
    expected = log_hit[0] + log_hit[1] + math.log(0.1)  # the third beam is a max-range reading
    got = float(_f(lab.beam_range_finder_model(z, z_star, prm, log=True)))
    assert np.isfinite(got) and got == pytest.approx(expected, rel=1e-9), (
        f"readings (3, 1, 5) for z* (1, 1, 2), z_short = z_rand = 0, sigma = 0.05: expected "
        f"log q = {expected:.4f} (the first beam 40 sigma out: log p_hit is about -800, its "
        f"p underflows), got {got!r}: compute that beam's log in log space"
    )


@grades("beam_range_finder_model", points=3)
@requires(*MODEL_VALUES)
def test_ranks_true_expected_ranges_first(lab):
    """The pose whose z* generated the scan is more likely than poses with shifted z*."""
    rng = np.random.default_rng(205)
    z_true = rng.uniform(0.5, 4.0, 60)
    z = np.clip(z_true + rng.normal(0.0, 0.05, 60), 0.0, 5.0)  # noise 4x below sigma_hit
    candidates = np.stack([np.clip(z_true + d, 0.0, 5.0) for d in (0.0, 0.1, -0.1, 0.3, -0.3, 1.0)])
    log_q = _f(lab.beam_range_finder_model(z, candidates, PARAMS, log=True))
    assert int(np.argmax(log_q)) == 0, (
        f"z* shifted by 0, 0.1, -0.1, 0.3, -0.3, 1.0 m: expected the unshifted z* most likely, "
        f"got log q {np.round(log_q, 2)}"
    )
    assert np.all(np.diff(log_q[[0, 1, 3, 5]]) < 0), (
        f"z* shifted by 0, 0.1, 0.3, 1.0 m: expected decreasing log q, got "
        f"{np.round(log_q[[0, 1, 3, 5]], 2)}"
    )


@grades("beam_range_finder_model", points=2)
@requires(*MODEL_VALUES)
def test_beam_model_rejects_bad_params(lab, refuses):
    """beam_range_finder_model: weights not summing to 1, a negative weight, sigma, lambda <= 0."""
    z, z_star = np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.5, 3.0])
    for what, bad in (
        ("z_hit = 0.9, so that the weights sum to 1.2", dict(PARAMS, z_hit=0.9)),
        (
            "z_max = -0.05, a negative weight (the sum is still 1)",
            dict(PARAMS, z_hit=0.8, z_max=-0.05),
        ),
        ("sigma_hit = -0.2", dict(PARAMS, sigma_hit=-0.2)),
        ("lambda_short = 0", dict(PARAMS, lambda_short=0.0)),
        ("max_range = -5", dict(PARAMS, max_range=-5.0)),
    ):
        with refuses(ValueError, f"params with {what}"):
            lab.beam_range_finder_model(z, z_star, bad)


@grades("beam_range_finder_model", points=3)
@requires(*MODEL_VALUES)
def test_beam_model_rejects_bad_readings_and_shapes(lab, refuses):
    """beam_range_finder_model: readings outside [0, max_range], z* beyond it, shape mismatches."""
    z, z_star = np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.5, 3.0])
    for bad_z in ([1.0, 5.5, 3.0], [1.0, -0.1, 3.0]):  # map no-returns to max_range first
        with refuses(ValueError, f"z = {bad_z}, a reading outside [0, max_range = 5]"):
            lab.beam_range_finder_model(np.array(bad_z), z_star, PARAMS)
    with refuses(ValueError, "z_star = (1, 6, 3), an expected range beyond max_range = 5"):
        lab.beam_range_finder_model(z, np.array([1.0, 6.0, 3.0]), PARAMS)  # z* beyond max_range
    with refuses(ValueError, "3 readings z for 4 expected ranges z_star"):
        lab.beam_range_finder_model(z, np.ones(4), PARAMS)  # 3 readings, 4 expected ranges
    with refuses(ValueError, "z of shape (3, 5) (3 scans) and z_star of shape (4, 5) (4 poses)"):
        lab.beam_range_finder_model(np.ones((3, 5)), np.ones((4, 5)), PARAMS)  # 3 scans, 4 poses


# ============================ pose_likelihood_map (20) ============================
MAZE_PARAMS = {
    "z_hit": 0.85,
    "z_short": 0.05,
    "z_max": 0.05,
    "z_rand": 0.05,
    "sigma_hit": 0.1,
    "lambda_short": 0.5,
    "max_range": 4.0,
}
BEAMS = np.linspace(-np.pi, np.pi, 37)[:-1]  # 36 beams, 10 degrees apart


@pytest.fixture(scope="module")
def maze():
    return load_maze()


@grades("pose_likelihood_map", points=8)
def test_likelihood_map_matches_ray_cast_oracle(lab, maze):
    """(P, H) log-likelihoods equal the beam model on cast_rays' z* for each position, heading."""
    rng = np.random.default_rng(301)
    positions = rng.uniform(0.3, 9.8, (15, 2))
    headings = rng.uniform(-np.pi, np.pi, 4)
    scan = np.clip(rng.uniform(0.0, 4.5, 36), 0.0, 4.0)  # some readings exactly max_range
    got = _f(lab.pose_likelihood_map(scan, maze, BEAMS, MAZE_PARAMS, positions, headings))
    assert got.shape == (15, 4), (
        f"15 positions, 4 headings: expected (P, H) = (15, 4), got {got.shape}"
    )
    for h, theta in enumerate(headings):
        poses = np.column_stack([positions, np.full(15, theta)])
        z_star = cast_rays(maze, poses, BEAMS, MAZE_PARAMS["max_range"])
        expected = [_loop_model(scan, z_star[p], MAZE_PARAMS)[1] for p in range(15)]
        # rtol: the sum of 36 logs computed in a different order (and a ray exactly through
        # a cell corner may pick either neighbour, a set of measure zero for random poses).
        np.testing.assert_allclose(
            got[:, h],
            expected,
            rtol=1e-7,
            err_msg=f"heading {theta:.3f} rad (column {h}): expected the log-likelihood of the "
            "scan given z* = cast_rays at (x, y, heading) with beam angles heading + BEAMS",
        )


@grades("pose_likelihood_map", points=9)
@requires("test_likelihood_map_matches_ray_cast_oracle")
def test_true_pose_ranks_highest_in_the_maze(lab, maze):
    """A scan simulated at a pose in the maze (cast_rays + noise) is most likely at that pose."""
    rng = np.random.default_rng(302)
    true = np.array([4.37, 6.12, 0.6])  # a free spot in a corridor
    z_star = cast_rays(maze, true, BEAMS, MAZE_PARAMS["max_range"])[0]
    assert z_star.min() > 0.1, "test setup: the true pose must be in free space"
    # Noise sd 0.02 m, a fifth of sigma_hit: the truth's expected log-likelihood beats a
    # pose whose z* differ by 0.1 m on a few beams by many nats.
    scan = np.where(
        z_star >= MAZE_PARAMS["max_range"],
        MAZE_PARAMS["max_range"],
        np.clip(z_star + rng.normal(0.0, 0.02, z_star.size), 0.0, _below(4.0)),
    )
    g = np.arange(0.275, 10.15, 0.5)
    lattice = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    positions = np.vstack([lattice, true[:2]])
    headings = np.concatenate([np.linspace(-np.pi, np.pi, 9)[:-1], [true[2]]])
    log_l = _f(lab.pose_likelihood_map(scan, maze, BEAMS, MAZE_PARAMS, positions, headings))
    assert log_l.shape == (positions.shape[0], headings.size) and np.all(~np.isnan(log_l)), (
        f"{positions.shape[0]} positions, {headings.size} headings: expected a NaN-free "
        f"({positions.shape[0]}, {headings.size}) array, got shape {log_l.shape}"
    )
    best = np.unravel_index(int(np.argmax(log_l)), log_l.shape)
    assert best == (positions.shape[0] - 1, headings.size - 1), (
        f"a scan simulated at {true}: expected the true pose to be most likely, got position "
        f"{positions[best[0]]}, heading {headings[best[1]]:.2f}"
    )
    margin = float(log_l[-1, -1] - np.max(log_l[:-1]))
    assert margin > 5.0, (
        f"a scan simulated at {true}: expected the truth to beat every lattice pose by more "
        f"than 5 nats, got {margin:.2f}"
    )


@grades("pose_likelihood_map", points=3)
@requires("test_likelihood_map_matches_ray_cast_oracle")
def test_likelihood_map_rejects_bad_input(lab, refuses, maze):
    """Scan/beam angles of different lengths, positions not (P, 2), bad params: ValueError."""
    scan = np.full(36, 1.0)
    with refuses(ValueError, "a scan of 35 readings for 36 beam_angles"):
        lab.pose_likelihood_map(scan[:-1], maze, BEAMS, MAZE_PARAMS, np.ones((2, 2)), np.zeros(1))
    with refuses(ValueError, "positions of shape (2, 3), not (P, 2)"):
        lab.pose_likelihood_map(scan, maze, BEAMS, MAZE_PARAMS, np.ones((2, 3)), np.zeros(1))
    with refuses(
        ValueError, "params with z_hit = 0.5, so that the mixture weights do not sum to 1"
    ):
        lab.pose_likelihood_map(
            scan, maze, BEAMS, dict(MAZE_PARAMS, z_hit=0.5), np.ones((2, 2)), np.zeros(1)
        )
