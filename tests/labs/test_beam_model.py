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
pose_likelihood_map 20.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import simpson

from robolab.maps import load_maze
from robolab.raycast import cast_rays

grades = pytest.mark.grades

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
    total = simpson(_f(lab.p_hit(z, z_star, z_max, sigma)), x=z)
    assert total == pytest.approx(1.0, abs=1e-8), (
        f"integral over [0, z_max] is {total}, not 1: check eta"
    )


@grades("p_hit", points=4)
def test_p_hit_reference_values_and_broadcasting(lab):
    """p_hit matches eta N(z; z*, sigma^2) with eta from the normal CDF, and broadcasts."""
    z = np.array([[0.0], [1.0], [2.5], [4.99], [5.0]])  # (5, 1)
    z_star = np.array([0.5, 2.5, 4.8])  # (3,)
    got = _f(lab.p_hit(z, z_star, 5.0, 0.4))
    assert got.shape == (5, 3), (
        f"z (5, 1) and z_star (3,) should broadcast to (5, 3), got {got.shape}"
    )
    expected = np.array([[_ref_p_hit(a, b, 5.0, 0.4) for b in z_star] for a in z[:, 0]])
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-300)
    # At the mode with a wide Gaussian the truncation matters: eta = 1 / (Phi(1.25) - Phi(-1.25)).
    assert float(_f(lab.p_hit(2.5, 2.5, 5.0, 2.0))) == pytest.approx(
        _ref_p_hit(2.5, 2.5, 5.0, 2.0), rel=1e-9
    )


@grades("p_hit", points=3)
def test_p_hit_support_and_continuity(lab):
    """p_hit is 0 outside [0, z_max], positive and continuous inside, never NaN."""
    outside = _f(lab.p_hit(np.array([-1.0, -1e-9, 5.0 + 1e-9, 7.0]), 2.0, 5.0, 0.5))
    np.testing.assert_array_equal(outside, 0.0)
    z = np.linspace(1e-6, 5.0 - 1e-6, 100001)
    f = _f(lab.p_hit(z, 2.0, 5.0, 0.5))
    assert np.all(np.isfinite(f)) and np.all(f > 0)
    # |f'| <= eta * max N' = eta / (sigma^2 sqrt(2 pi e)) < 1.1 / 0.25 / 4.13 < 1.1 per metre,
    # so neighbours h = 5e-5 m apart differ by less than 1e-4.
    assert np.max(np.abs(np.diff(f))) < 1e-4, "p_hit jumps inside (0, z_max)"
    # Far tails: tiny but not NaN.
    far = _f(lab.p_hit(np.array([0.0, 5.0]), 2.5, 5.0, 0.01))
    assert np.all(np.isfinite(far)) and np.all(far >= 0)


@grades("p_hit", points=2)
def test_p_hit_rejects_bad_input(lab):
    """Sigma <= 0, z* beyond z_max (or negative), non-broadcasting shapes raise ValueError."""
    with pytest.raises(ValueError):
        lab.p_hit(1.0, 1.0, 5.0, -0.1)
    with pytest.raises(ValueError):
        lab.p_hit(1.0, 1.0, 5.0, 0.0)
    with pytest.raises(ValueError):
        lab.p_hit(1.0, 6.0, 5.0, 0.1)
    with pytest.raises(ValueError):
        lab.p_hit(1.0, -0.5, 5.0, 0.1)
    with pytest.raises(ValueError):
        lab.p_hit(np.ones(3), np.ones(4), 5.0, 0.1)


# ================================ p_short (12) ================================
@grades("p_short", points=1)  # per case: 4 points
@pytest.mark.parametrize("z_star, lam", [(2.0, 0.5), (4.0, 3.0), (0.1, 0.01), (8.0, 20.0)])
def test_p_short_integrates_to_one(lab, z_star, lam):
    """p_short integrates to 1 over [0, z*] (the exponential's eta) and is 0 beyond z*."""
    # Simpson on 200001 nodes of [0, z*]: error <= h^4 lam^5 z* / 180 < 1e-9 for these values.
    z = np.linspace(0.0, z_star, 200001)
    total = simpson(_f(lab.p_short(z, z_star, lam)), x=z)
    assert total == pytest.approx(1.0, abs=1e-7), (
        f"integral over [0, z*] is {total}, not 1: check eta"
    )
    beyond = _f(lab.p_short(np.array([z_star * 1.001, z_star + 1.0, -0.1]), z_star, lam))
    np.testing.assert_array_equal(beyond, 0.0)


@grades("p_short", points=4)
def test_p_short_reference_values(lab):
    """p_short = lambda e^{-lambda z} / (1 - e^{-lambda z*}) on [0, z*]; decreasing; broadcasts."""
    z = np.array([[0.0], [0.5], [1.0], [2.9]])
    z_star = np.array([1.0, 3.0])
    got = _f(lab.p_short(z, z_star, 1.5))
    assert got.shape == (4, 2)
    expected = np.array([[_ref_p_short(a, b, 1.5) for b in z_star] for a in z[:, 0]])
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    inside = _f(lab.p_short(np.linspace(0.0, 3.0, 50), 3.0, 1.5))
    assert np.all(np.diff(inside) < 0), "p_short must decrease on [0, z*]"


@grades("p_short", points=2)
def test_p_short_small_and_zero_z_star(lab):
    """z* -> 0 is handled: finite, non-negative, never NaN; no reading beyond z* = 0 is short."""
    at_zero = _f(lab.p_short(np.array([0.0, 0.5, 2.0]), 0.0, 1.0))
    assert np.all(np.isfinite(at_zero)) and np.all(at_zero >= 0), f"p_short(z, z*=0) = {at_zero}"
    np.testing.assert_array_equal(at_zero[1:], 0.0)
    # Small z*: eta ~ 1 / (lambda z*), so p_short(0) ~ 1 / z* = 1e6; finite and accurate.
    small = float(_f(lab.p_short(0.0, 1e-6, 2.0)))
    assert small == pytest.approx(2.0 / -math.expm1(-2e-6), rel=1e-6)


@grades("p_short", points=2)
def test_p_short_rejects_bad_input(lab):
    """lambda_short <= 0 and negative z* raise ValueError."""
    with pytest.raises(ValueError):
        lab.p_short(1.0, 2.0, 0.0)
    with pytest.raises(ValueError):
        lab.p_short(1.0, 2.0, -1.0)
    with pytest.raises(ValueError):
        lab.p_short(1.0, -2.0, 1.0)


# ================================ p_max (6) ================================
@grades("p_max", points=4)
def test_p_max_is_a_point_mass_at_exactly_z_max(lab):
    """p_max is 1 at exactly z_max and 0 everywhere else, even 1 ulp away."""
    z = np.array([0.0, 2.0, _below(5.0), 5.0, float(np.nextafter(5.0, np.inf)), 7.0])
    np.testing.assert_array_equal(_f(lab.p_max(z, 5.0)), [0, 0, 0, 1, 0, 0])
    grid = _f(lab.p_max(np.array([[30.0, 29.99], [0.0, 30.0]]), 30.0))
    np.testing.assert_array_equal(grid, [[1, 0], [0, 1]])
    assert float(_f(lab.p_max(3.5, 3.5))) == 1.0


@grades("p_max", points=2)
def test_p_max_rejects_bad_input(lab):
    """A non-positive z_max raises ValueError."""
    with pytest.raises(ValueError):
        lab.p_max(1.0, 0.0)
    with pytest.raises(ValueError):
        lab.p_max(1.0, -5.0)


# ================================ p_rand (8) ================================
@grades("p_rand", points=5)
def test_p_rand_uniform_on_half_open_range(lab):
    """p_rand is 1/z_max on [0, z_max), 0 at z_max and outside, and integrates to 1."""
    for z_max in (1.0, 5.0, 30.0):
        z = np.linspace(0.0, _below(z_max), 10001)
        f = _f(lab.p_rand(z, z_max))
        np.testing.assert_allclose(f, 1.0 / z_max, rtol=1e-12)
        # The integrand is constant: the trapezoid rule is exact up to the 1-ulp gap at z_max.
        assert np.trapezoid(f, z) == pytest.approx(1.0, rel=1e-12)
        outside = _f(lab.p_rand(np.array([z_max, -0.1, z_max + 1.0]), z_max))
        np.testing.assert_array_equal(
            outside, 0.0, err_msg=f"z_max = {z_max}: [0, z_max) is half-open"
        )


@grades("p_rand", points=3)
def test_p_rand_shape_and_bad_input(lab):
    """p_rand keeps the shape of z; a non-positive z_max raises ValueError."""
    got = _f(lab.p_rand(np.full((3, 4), 1.0), 2.0))
    assert got.shape == (3, 4)
    np.testing.assert_allclose(got, 0.5)
    with pytest.raises(ValueError):
        lab.p_rand(1.0, 0.0)
    with pytest.raises(ValueError):
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
            f"z (N, 1) with z_star (N, 1) should give (N,), got {q.shape}"
        )
        total += simpson(q, x=nodes)
    assert total == pytest.approx(1.0 - PARAMS["z_max"], abs=1e-6)
    at_max = float(_f(lab.beam_range_finder_model(np.array([zmax]), np.array([z_star]), PARAMS)))
    assert at_max >= PARAMS["z_max"] - 1e-12


@grades("beam_range_finder_model", points=4)
def test_mixture_point_mass_at_exactly_max_range(lab):
    """A reading of exactly max_range gets the z_max weight; 1 ulp below, the z_rand density."""
    zmax = PARAMS["max_range"]
    # z* = 2 m, sigma = 0.1 m: p_hit at 5 m is 30 sigma out (< 1e-190) and p_short is 0 beyond z*.
    prm = dict(PARAMS, sigma_hit=0.1)
    z = np.array([[zmax], [_below(zmax)]])
    q = _f(lab.beam_range_finder_model(z, np.full((2, 1), 2.0), prm))
    assert q[0] == pytest.approx(prm["z_max"], rel=1e-9), (
        "a max-range reading is explained by z_max * p_max"
    )
    assert q[1] == pytest.approx(prm["z_rand"] / zmax, rel=1e-9), (
        "just below max_range only p_rand remains"
    )


@grades("beam_range_finder_model", points=3)
def test_mixture_continuity_and_support(lab):
    """One beam: continuous on (0, z*) and (z*, z_max), positive on [0, z_max] when z_rand > 0."""
    z_star = 2.5
    for a, b in ((1e-6, z_star - 1e-6), (z_star + 1e-6, 5.0 - 1e-6)):
        z = np.linspace(a, b, 50001)
        q = _f(lab.beam_range_finder_model(z[:, None], np.full((z.size, 1), z_star), PARAMS))
        assert np.all(np.isfinite(q)) and np.all(q > 0)
        # |dq/dz| <= z_hit eta |N'| + z_short eta lambda^2
        #        < 0.7 * 1.0 * 6.1 + 0.15 * 1.2 * 0.64 < 5 per metre,
        # and h = 5e-5 m: neighbours differ by less than 2.5e-4.
        assert np.max(np.abs(np.diff(q))) < 2.5e-4, "the mixture jumps inside a smooth piece"
    # The jump at z* is the short component's: z_short * eta * lambda * e^{-lambda z*}.
    q = _f(
        lab.beam_range_finder_model(
            np.array([[z_star], [float(np.nextafter(z_star, 9))]]), np.full((2, 1), z_star), PARAMS
        )
    )
    jump = PARAMS["z_short"] * _ref_p_short(z_star, z_star, PARAMS["lambda_short"])
    assert q[0] - q[1] == pytest.approx(jump, rel=1e-6)


@grades("beam_range_finder_model", points=5)
def test_product_equals_exp_of_log_form(lab):
    """q (log=False) equals exp(log q) (log=True) for one pose and for many poses."""
    rng = np.random.default_rng(202)
    z, z_star = _random_scan(rng, 20, 30, PARAMS["max_range"])
    q = _f(lab.beam_range_finder_model(z, z_star, PARAMS))
    log_q = _f(lab.beam_range_finder_model(z, z_star, PARAMS, log=True))
    assert q.shape == log_q.shape == (20,)
    # 30 beams keep q well inside the double range, so exp(log q) is accurate to ~30 ulp per beam.
    np.testing.assert_allclose(q, np.exp(log_q), rtol=1e-9)
    one = float(_f(lab.beam_range_finder_model(z[0], z_star[0], PARAMS, log=True)))
    assert one == pytest.approx(log_q[0], rel=1e-12)


@grades("beam_range_finder_model", points=8)
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
        _f(lab.beam_range_finder_model(z, z_star, prm)), expected[:, 0], rtol=1e-9
    )
    np.testing.assert_allclose(
        _f(lab.beam_range_finder_model(z, z_star, prm, log=True)), expected[:, 1], rtol=1e-9
    )
    # One scan (B,) against many poses (N, B).
    expected_one = np.array([_loop_model(z[0], z_star[i], prm)[1] for i in range(12)])
    got = _f(lab.beam_range_finder_model(z[0], z_star, prm, log=True))
    assert got.shape == (12,)
    np.testing.assert_allclose(got, expected_one, rtol=1e-9)
    # One scan, one pose: a single number.
    single = _f(lab.beam_range_finder_model(z[3], z_star[3], prm))
    assert single.shape == () and float(single) == pytest.approx(expected[3, 0], rel=1e-9)


@grades("beam_range_finder_model", points=5)
def test_log_form_does_not_underflow(lab):
    """3000 beams: the product underflows to 0.0 but the log form stays finite and exact."""
    rng = np.random.default_rng(204)
    z, z_star = _random_scan(rng, 1, 3000, PARAMS["max_range"])
    expected_log = _loop_model(z[0], z_star[0], PARAMS)[1]
    assert expected_log < -1000  # so the product of the per-beam p is below 1e-434: 0.0 in doubles
    log_q = float(_f(lab.beam_range_finder_model(z[0], z_star[0], PARAMS, log=True)))
    assert np.isfinite(log_q), "log=True must sum logs per beam, not take the log of the product"
    assert log_q == pytest.approx(expected_log, rel=1e-10)
    assert float(_f(lab.beam_range_finder_model(z[0], z_star[0], PARAMS))) == 0.0


@grades("beam_range_finder_model", points=4)
def test_ranks_true_expected_ranges_first(lab):
    """The pose whose z* generated the scan is more likely than poses with shifted z*."""
    rng = np.random.default_rng(205)
    z_true = rng.uniform(0.5, 4.0, 60)
    z = np.clip(z_true + rng.normal(0.0, 0.05, 60), 0.0, 5.0)  # noise 4x below sigma_hit
    candidates = np.stack([np.clip(z_true + d, 0.0, 5.0) for d in (0.0, 0.1, -0.1, 0.3, -0.3, 1.0)])
    log_q = _f(lab.beam_range_finder_model(z, candidates, PARAMS, log=True))
    assert int(np.argmax(log_q)) == 0
    assert np.all(np.diff(log_q[[0, 1, 3, 5]]) < 0), "larger errors must be less likely"


@grades("beam_range_finder_model", points=5)
def test_beam_model_rejects_bad_input(lab):
    """Bad weights, negative sigma, z* beyond max_range and mismatched shapes raise ValueError."""
    z, z_star = np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.5, 3.0])
    lab.beam_range_finder_model(z, z_star, PARAMS)  # valid: must not raise
    for bad in (
        dict(PARAMS, z_hit=0.9),  # weights sum to 1.2
        dict(PARAMS, z_hit=0.8, z_max=-0.05),  # a negative weight (the sum is still 1)
        dict(PARAMS, sigma_hit=-0.2),
        dict(PARAMS, lambda_short=0.0),
        dict(PARAMS, max_range=-5.0),
    ):
        with pytest.raises(ValueError):
            lab.beam_range_finder_model(z, z_star, bad)
    with pytest.raises(ValueError):
        lab.beam_range_finder_model(z, np.array([1.0, 6.0, 3.0]), PARAMS)  # z* beyond max_range
    with pytest.raises(ValueError):
        lab.beam_range_finder_model(z, np.ones(4), PARAMS)  # 3 readings, 4 expected ranges
    with pytest.raises(ValueError):
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


@grades("pose_likelihood_map", points=7)
def test_likelihood_map_matches_ray_cast_oracle(lab, maze):
    """(P, H) log-likelihoods equal the beam model on cast_rays' z* for each position, heading."""
    rng = np.random.default_rng(301)
    positions = rng.uniform(0.3, 9.8, (15, 2))
    headings = rng.uniform(-np.pi, np.pi, 4)
    scan = np.clip(rng.uniform(0.0, 4.5, 36), 0.0, 4.0)  # some readings exactly max_range
    got = _f(lab.pose_likelihood_map(scan, maze, BEAMS, MAZE_PARAMS, positions, headings))
    assert got.shape == (15, 4), f"expected (P, H) = (15, 4), got {got.shape}"
    for h, theta in enumerate(headings):
        poses = np.column_stack([positions, np.full(15, theta)])
        z_star = cast_rays(maze, poses, BEAMS, MAZE_PARAMS["max_range"])
        expected = [_loop_model(scan, z_star[p], MAZE_PARAMS)[1] for p in range(15)]
        # rtol: the sum of 36 logs computed in a different order (and a ray exactly through
        # a cell corner may pick either neighbour, a set of measure zero for random poses).
        np.testing.assert_allclose(got[:, h], expected, rtol=1e-7)


@grades("pose_likelihood_map", points=10)
def test_true_pose_ranks_highest_in_the_maze(lab, maze):
    """A scan simulated at a pose in the maze (cast_rays + noise) is most likely at that pose."""
    rng = np.random.default_rng(302)
    true = np.array([4.37, 6.12, 0.6])  # a free spot in a corridor
    z_star = cast_rays(maze, true, BEAMS, MAZE_PARAMS["max_range"])[0]
    assert z_star.min() > 0.1, "the true pose must be in free space"
    # Noise sd 0.02 m, a fifth of sigma_hit: the truth's expected log-likelihood beats a
    # pose whose z* differ by 0.1 m on a few beams by many nats.
    scan = np.where(
        z_star >= MAZE_PARAMS["max_range"],
        MAZE_PARAMS["max_range"],
        np.clip(z_star + rng.normal(0.0, 0.02, z_star.size), 0.0, _below(4.0)),
    )
    # Candidates: a 0.5 m lattice of cell centres (free or not), plus the true position.
    g = np.arange(0.275, 10.15, 0.5)
    lattice = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    positions = np.vstack([lattice, true[:2]])
    headings = np.concatenate([np.linspace(-np.pi, np.pi, 9)[:-1], [true[2]]])
    log_l = _f(lab.pose_likelihood_map(scan, maze, BEAMS, MAZE_PARAMS, positions, headings))
    assert log_l.shape == (positions.shape[0], headings.size)
    assert np.all(~np.isnan(log_l))
    best = np.unravel_index(int(np.argmax(log_l)), log_l.shape)
    assert best == (positions.shape[0] - 1, headings.size - 1), (
        f"best pose is {positions[best[0]]}, heading {headings[best[1]]:.2f}; truth is {true}"
    )
    # The truth beats every lattice pose by a clear margin (the nearest is 0.13 m away).
    assert log_l[-1, -1] - np.max(log_l[:-1]) > 5.0


@grades("pose_likelihood_map", points=3)
def test_likelihood_map_rejects_bad_input(lab, maze):
    """Scan/beam angles of different lengths, positions not (P, 2), bad params: ValueError."""
    scan = np.full(36, 1.0)
    with pytest.raises(ValueError):
        lab.pose_likelihood_map(scan[:-1], maze, BEAMS, MAZE_PARAMS, np.ones((2, 2)), np.zeros(1))
    with pytest.raises(ValueError):
        lab.pose_likelihood_map(scan, maze, BEAMS, MAZE_PARAMS, np.ones((2, 3)), np.zeros(1))
    with pytest.raises(ValueError):
        lab.pose_likelihood_map(
            scan, maze, BEAMS, dict(MAZE_PARAMS, z_hit=0.5), np.ones((2, 2)), np.zeros(1)
        )
