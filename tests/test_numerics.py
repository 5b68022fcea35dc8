"""Accepted input never gives NaN or a silently wrong number: extreme magnitudes, every function.

For each probability / filter function the class of inputs is swept over magnitudes
from 1e-300 to 1e300. The contract: either a clear ValueError naming the argument,
or the right value, checked against an oracle (a scaling law, an analytic limit or
the same computation at ordinary magnitudes).
"""

from __future__ import annotations

import numpy as np
import pytest

from robolab.geometry import transform_points, wrap_angle
from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays
from solutions import beam_model as bm
from solutions import fastslam as fs
from solutions import landmark_pf as lp
from solutions import mcl
from solutions import odometry_mapping as om
from solutions.ekf_mapping import ekf_mapping_step

MAGNITUDES = [1e-300, 1e-200, 1e-30, 1e-3, 1.0, 1e3, 1e30, 1e200, 1e300]


# -- wrap_angle ---------------------------------------------------------------------------
@pytest.mark.parametrize("a", [1e-300, 1.0, 3.2, 1e10, 1e200, 1e300, -1e300])
def test_wrap_angle_of_finite_angles_is_in_range_and_congruent(a):
    w = wrap_angle(a)
    assert -np.pi <= w < np.pi
    # congruent modulo 2 pi to the float given (checked where the float still resolves it)
    if abs(a) < 1e6:
        assert np.isclose(np.cos(w), np.cos(a)) and np.isclose(np.sin(w), np.sin(a))


@pytest.mark.parametrize("a", [np.inf, -np.inf, [0.0, np.inf]])
def test_wrap_angle_of_an_infinite_angle_raises(a):
    with pytest.raises(ValueError, match="finite"):
        wrap_angle(a)


def test_wrap_angle_keeps_nan_as_missing():
    assert np.isnan(wrap_angle(np.nan))
    out = wrap_angle(np.array([np.nan, 4.0]))
    assert np.isnan(out[0]) and np.isclose(out[1], 4.0 - 2 * np.pi)


# -- landmark_pf ----------------------------------------------------------------------------
LANDMARKS = np.array([[1.0, 0.0], [0.0, 2.0], [3.0, 3.0]])
PARTICLES = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 1.0], [2.0, -1.0, 0.0]])


@pytest.mark.parametrize("sigma", MAGNITUDES)
def test_measurement_probability_is_finite_or_refuses_the_noise(sigma):
    z = np.hypot(*(LANDMARKS - PARTICLES[0, :2]).T)  # particle 0 measures exactly
    try:
        w = lp.measurement_probability(z, PARTICLES, LANDMARKS, sigma)
    except ValueError as exc:
        assert "sensor_noise" in str(exc)
        assert sigma < 1e-30  # only a density that truly overflows is refused
        return
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    # the exact particle's density is the analytic peak (2 pi sigma^2)^(-K/2)
    np.testing.assert_allclose(
        w[0], np.exp(-1.5 * np.log(2 * np.pi) - 3 * np.log(sigma)), rtol=1e-12
    )
    assert w[0] >= w[1:].max()


@pytest.mark.parametrize("scale", [1e-300, 1e-100, 1.0, 1e100, 1e150, 1e200, 1e300])
def test_measurement_probability_at_far_coordinates_is_the_exact_peak(scale):
    """A particle that measures its landmarks exactly has the peak density, at any scale."""
    lm = np.array([[scale, 0.0], [0.0, scale]])
    w = lp.measurement_probability([scale, scale], [[0.0, 0.0, 0.0]], lm, 1.0)
    np.testing.assert_allclose(w, [1 / (2 * np.pi)], rtol=1e-12)


@pytest.mark.parametrize("scale", [1e-300, 1e-100, 1e-10, 1.0, 1e100, 1e300, 1e308])
def test_low_variance_resample_is_invariant_to_the_weights_scale(scale):
    rng0, rng1 = np.random.default_rng(3), np.random.default_rng(3)
    particles = np.arange(20.0)[:, None]
    base = np.random.default_rng(1).uniform(0.0, 1.0, 20)
    base[5] = 0.0
    w = np.minimum(base * scale, np.finfo(float).max)  # 1e308 * 0.99: all near the top
    ref = lp.low_variance_resample(particles, base, rng0)
    out = lp.low_variance_resample(particles, w, rng1)
    np.testing.assert_array_equal(out, ref)
    assert 5.0 not in out[:, 0]  # the zero-weight particle is never drawn


def test_low_variance_resample_of_equal_huge_weights_takes_each_particle_once():
    p = np.arange(10.0)[:, None]
    out = lp.low_variance_resample(p, np.full(10, 1e308), np.random.default_rng(0))
    np.testing.assert_array_equal(np.sort(out[:, 0]), p[:, 0])


# -- Bayes filter and normalization ----------------------------------------------------
@pytest.mark.parametrize("scale", [5e-324, 1e-310, 1e-300, 1e-100, 1.0, 1e100, 1e300, 8e307])
def test_bayes_posteriors_and_normalize_depend_only_on_likelihood_ratios(scale):
    from solutions import bayes, demo

    ratios = np.array([1.0, 2.0, 0.0, 1.0])
    prior = np.array([0.1, 0.2, 0.3, 0.4])
    ref = ratios * prior / np.sum(ratios * prior)
    like = ratios * scale  # the sum overflows at 8e307, the products underflow below 1e-300
    np.testing.assert_allclose(bayes.bayes_posterior(like, prior), ref, rtol=1e-12)
    np.testing.assert_allclose(bayes.bayes_filter_step(prior, np.eye(4), like), ref, rtol=1e-12)
    np.testing.assert_allclose(demo.normalize(like), ratios / ratios.sum(), rtol=1e-12)


# -- mcl --------------------------------------------------------------------------------------
@pytest.mark.parametrize("epsilon", MAGNITUDES)
@pytest.mark.parametrize("k", [1, 2, 100, 10_000])
def test_kld_sample_size_is_a_positive_int_or_refuses_epsilon(epsilon, k):
    try:
        n = mcl.kld_sample_size(k, epsilon, 2.326)
    except ValueError as exc:
        assert "epsilon" in str(exc) and epsilon < 1e-3
        return
    assert isinstance(n, int) and n >= 1
    # monotone: a tighter bound never needs fewer particles
    if epsilon < 1e300:
        assert n >= mcl.kld_sample_size(k, epsilon * 10, 2.326)


def test_kld_sample_size_never_wraps_to_negative():
    with pytest.raises(ValueError, match="epsilon"):
        mcl.kld_sample_size(100, 1e-300, 2.326)
    with pytest.raises(ValueError, match="epsilon"):
        mcl.kld_sample_size(np.array([1, 100]), 1e-300, 2.326)
    assert mcl.kld_sample_size(1, 1e-300, 2.326) == 1  # one bin needs one sample


@pytest.mark.parametrize("corrected", [False, True])
def test_motion_model_in_blocks_gives_the_whole_arrays_bits(corrected, monkeypatch):
    """Blocks of particles, in place: the same draws and the same operations as on whole
    (N,) arrays (the formula of Table 5.6 written out here), bit for bit."""
    rng = np.random.default_rng(7)
    particles = np.column_stack([rng.uniform(-5, 5, (23, 2)), rng.uniform(-3.2, 3.2, 23)])
    particles[::4, 2] += 30.0  # headings many turns away: wrap_angle's general path
    prev, now, alphas = (0.3, -0.2, 3.0), (0.5, 0.1, -2.9), (0.1, 0.2, 0.05, 0.3)
    rot1, trans, rot2 = mcl._odometry_deltas(prev, now)
    n1, n2 = rot1, rot2
    if corrected:
        n1 = min(abs(mcl.angle_diff(rot1, 0.0)), abs(mcl.angle_diff(rot1, np.pi)))
        n2 = min(abs(mcl.angle_diff(rot2, 0.0)), abs(mcl.angle_diff(rot2, np.pi)))
    a = np.asarray(alphas)
    sd = np.sqrt(
        [
            a[0] * n1**2 + a[1] * trans**2,
            a[2] * trans**2 + a[3] * (n1**2 + n2**2),
            a[0] * n2**2 + a[1] * trans**2,
        ]
    )
    noise = np.random.default_rng(3).standard_normal((23, 3)) * sd
    heading = particles[:, 2] + (rot1 - noise[:, 0])
    tr = trans - noise[:, 1]
    want = np.column_stack(
        [
            particles[:, 0] + tr * np.cos(heading),
            particles[:, 1] + tr * np.sin(heading),
            mcl.wrap_angle(heading + (rot2 - noise[:, 2])),
        ]
    )
    monkeypatch.setattr(mcl, "MOTION_BLOCK", 5)  # several blocks, the last one partial
    got = mcl.sample_motion_model_odometry(
        particles, prev, now, alphas, np.random.default_rng(3), corrected=corrected
    )
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("spread", MAGNITUDES)
def test_normalize_log_weights_sums_to_one_at_any_spread(spread):
    w = mcl.normalize_log_weights(np.array([-spread, 0.0, spread, spread]))
    assert np.all(np.isfinite(w)) and np.isclose(w.sum(), 1.0)


@pytest.mark.parametrize("sigma", [5e-324, 1e-310, 1e-300, 1e-30, 1e-3, 1.0, 1e30, 1e300])
@pytest.mark.parametrize("max_dist", [1e-300, 1.0, 1e300])
def test_likelihood_field_model_is_finite_or_refuses_sigma(sigma, max_dist):
    data = np.zeros((40, 40))
    data[:, 30] = 1.0
    grid = OccupancyGrid(data, 0.05)
    scan = {
        "ranges": np.array([1.0, 1.2]),
        "angles": np.array([0.0, 0.3]),
        "range_min": 0.1,
        "range_max": 5.0,
    }
    try:
        field = mcl.likelihood_field(grid, sigma, max_dist)
    except ValueError as exc:
        assert "sigma_hit" in str(exc) and sigma < 1e-300
        return
    assert np.all(np.isfinite(field["likelihood"]))
    out = mcl.likelihood_field_model(
        scan, np.array([[0.5, 1.0, 0.0], [0.3, 1.0, 0.1]]), field, mcl.DEFAULT_PARAMS
    )
    assert np.all(np.isfinite(out))
    w = mcl.normalize_log_weights(out)
    assert np.all(np.isfinite(w)) and np.isclose(w.sum(), 1.0)


# -- beam model ----------------------------------------------------------------------------
@pytest.mark.parametrize("sigma", MAGNITUDES)
def test_p_hit_is_a_density_on_zero_to_zmax_at_any_sigma(sigma):
    z_max, z_star = 5.0, 2.0
    try:
        at_star = bm.p_hit(z_star, z_star, z_max, sigma)
    except ValueError as exc:
        assert "sigma_hit" in str(exc) and sigma < 1e-200
        return
    assert np.isfinite(at_star) and at_star > 0
    if sigma >= 1e30:  # a Gaussian far wider than [0, z_max] truncates to the uniform 1/z_max
        np.testing.assert_allclose(
            bm.p_hit(np.array([0.0, 4.9]), z_star, z_max, sigma), 1 / z_max, rtol=1e-12
        )
    if 1e-3 <= sigma <= 1e3:  # it integrates to one
        z = np.linspace(0.0, z_max, 200_001)
        assert np.trapezoid(bm.p_hit(z, z_star, z_max, sigma), z) == pytest.approx(1, rel=1e-4)


@pytest.mark.parametrize("sigma", [1e-3, 1.0, 1e3, 1e30, 1e300])
def test_beam_model_log_mixture_agrees_with_the_densities(sigma):
    params = {
        "z_hit": 0.7,
        "z_short": 0.1,
        "z_max": 0.1,
        "z_rand": 0.1,
        "sigma_hit": sigma,
        "lambda_short": 0.5,
        "max_range": 5.0,
    }
    z, z_star = np.array([1.0, 2.0, 5.0]), np.array([1.5, 1.5, 1.5])
    log_p = bm.beam_range_finder_model(z, z_star, params, log=True)
    assert np.isfinite(log_p)
    mix = (
        0.7 * bm.p_hit(z, z_star, 5.0, sigma)
        + 0.1 * bm.p_short(z, z_star, 0.5)
        + 0.1 * bm.p_max(z, 5.0)
        + 0.1 * bm.p_rand(z, 5.0)
    )
    assert log_p == pytest.approx(np.log(mix).sum(), rel=1e-9)


# -- log-odds -------------------------------------------------------------------------------
@pytest.mark.parametrize("m", MAGNITUDES + [np.inf])
def test_logodds_to_probability_is_in_unit_interval_and_antisymmetric(m):
    p = om.logodds_to_probability(np.array([-m, m]))
    assert np.all((p >= 0) & (p <= 1))
    assert p[0] + p[1] == pytest.approx(1.0)


# -- FastSLAM -------------------------------------------------------------------------------
MEAN = np.array([2.0, 1.0])
POSE = np.array([0.5, -0.2, 0.3])
Z = np.array([1.7, 0.45])
COV0 = np.array([[0.3, 0.05], [0.05, 0.2]])
QT0 = np.diag([0.01, 0.002])


@pytest.mark.parametrize("s", MAGNITUDES)
def test_update_landmark_obeys_the_covariance_scaling_law(s):
    """Scaling cov and Qt by s keeps the mean update, scales the covariance by s and
    shifts the log-likelihood analytically: the oracle is the s = 1 computation."""
    mu1, cov1, ll1 = fs.update_landmark(MEAN, COV0, Z, POSE, QT0)
    zhat = fs.h(MEAN, POSE)
    e = Z - zhat
    e[1] = wrap_angle(e[1])
    H = fs.h_jacobian(MEAN, POSE)
    S0 = H @ COV0 @ H.T + QT0
    maha0 = e @ np.linalg.solve(S0, e)
    try:
        mu, cov, ll = fs.update_landmark(MEAN, COV0 * s, Z, POSE, QT0 * s)
    except ValueError as exc:
        assert "cov" in str(exc) or "Qt" in str(exc) or "finite" in str(exc)
        return
    np.testing.assert_allclose(mu, mu1, rtol=1e-9)
    np.testing.assert_allclose(cov, cov1 * s, rtol=1e-9)
    expected = (
        -0.5 * maha0 / s - np.log(2 * np.pi) - 0.5 * (2 * np.log(s) + np.log(np.linalg.det(S0)))
    )
    if np.isfinite(expected):
        assert ll == pytest.approx(expected, rel=1e-9)
    assert not np.isnan(ll)


@pytest.mark.parametrize(
    "cov",
    [
        -np.eye(2),
        np.array([[1.0, 2.0], [2.0, 1.0]]),
        np.array([[1.0, 0.5], [0.0, 1.0]]),
        np.zeros((2, 2)),
    ],
)
def test_update_landmark_refuses_a_non_covariance(cov):
    with pytest.raises(ValueError, match="cov"):
        fs.update_landmark(MEAN, cov, Z, POSE, QT0)
    stack = np.stack([COV0, cov])  # the bad one is named by its index in the stack
    with pytest.raises(ValueError, match=r"cov\[1\]"):
        fs.update_landmark(np.stack([MEAN, MEAN]), stack, Z, np.stack([POSE, POSE]), QT0)


def _state(m=5, k=3):
    return fs.init_particles(m, k, np.zeros(3), init="first_observation")


@pytest.mark.parametrize("r", [1e160, 1e200, 1e300])
def test_fastslam_step_refuses_a_range_that_overflows_the_landmark(r):
    with pytest.raises(ValueError, match="observations"):
        fs.fastslam_step(
            _state(), [1.0, 0.0], [[r, 0.1, 1]], np.eye(3) * 1e-4, QT0, np.random.default_rng(0)
        )


@pytest.mark.parametrize("r", [1e-300, 1e-3, 1.0, 1e3, 1e100])
def test_fastslam_step_initializes_landmarks_at_any_representable_range(r):
    out = fs.fastslam_step(
        _state(), [0.0, 0.0], [[r, 0.1, 1]], np.eye(3) * 1e-12, QT0, np.random.default_rng(0)
    )
    assert all(np.all(np.isfinite(out[k])) for k in ("poses", "means", "covs", "weights"))
    assert out["seen"][:, 1].all()
    # the mean is the observation's inverse h at the particle's pose
    p = out["poses"]
    expected = p[:, :2] + r * np.stack([np.cos(p[:, 2] + 0.1), np.sin(p[:, 2] + 0.1)], -1)
    np.testing.assert_allclose(out["means"][:, 1], expected, rtol=1e-6, atol=1e-300)


def test_fastslam_step_with_a_tiny_qt_stays_finite():
    state = fs.fastslam_step(
        _state(),
        [0.0, 0.0],
        [[2.0, 0.1, 0]],
        np.eye(3) * 1e-12,
        np.eye(2) * 1e-300,
        np.random.default_rng(0),
    )
    out = fs.fastslam_step(
        state,
        [0.0, 0.0],
        [[2.0, 0.1, 0]],
        np.eye(3) * 1e-12,
        np.eye(2) * 1e-300,
        np.random.default_rng(1),
    )
    assert all(np.all(np.isfinite(out[k])) for k in ("poses", "means", "covs", "weights"))


# -- EKF mapping ----------------------------------------------------------------------------
@pytest.mark.parametrize("bad", ["P", "Q", "R"])
def test_ekf_mapping_step_refuses_an_indefinite_covariance(bad):
    ekf = {
        "x": np.array([10.0, 10.0, 0.0]),
        "P": np.eye(3) * 0.01,
        "Q": np.eye(3) * 1e-3,
        "R": np.eye(36) * 0.04,
    }
    ekf[bad] = -np.eye(ekf[bad].shape[0])
    with pytest.raises(ValueError, match=f"ekf {bad}"):
        ekf_mapping_step(ekf, np.zeros((40, 40)), 1.0, 0.0, np.full(36, 5.0), 0.1)


# -- ray casting and beams ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def box():
    data = np.zeros((40, 60))
    data[:, 50] = 1.0  # a wall at x in [2.5, 2.55) m
    return OccupancyGrid(data, 0.05, np.array([-0.5, 0.3, 0.2]))


@pytest.mark.parametrize("max_range", [1e2, 1e30, 1e200, 1e300, 1e308, np.finfo(float).max])
def test_cast_rays_with_a_huge_max_range_matches_an_ordinary_one(box, max_range):
    poses = np.array([[0.3, 1.2, 0.0], [0.3, 1.2, 0.1], [-5.0, -5.0, 0.0]])
    angles = np.linspace(-np.pi, np.pi, 37)
    ref = cast_rays(box, poses, angles, 50.0)
    out = cast_rays(box, poses, angles, max_range)
    assert np.all(np.isfinite(out)) and np.all(out <= max_range)
    hit = ref < 50.0
    np.testing.assert_allclose(out[hit], ref[hit], rtol=1e-12)
    assert np.all(out[~hit] == max_range)


@pytest.mark.parametrize("end", [[1e9, 1e9], [0.0, 1e12], [1e300, 0.0]])
def test_beam_cells_refuses_beams_too_long_to_allocate(end):
    with pytest.raises(ValueError, match="MAX_BEAM_CELLS"):
        om.beam_cells([0.0, 0.0], end)


def test_beam_cells_still_traces_long_beams_within_the_bound():
    cells, beam = om.beam_cells([0.5, 0.5], [0.5, 100_000.5])
    assert cells.shape == (100_001, 2) and np.all(cells[:, 0] == 0)


# -- the alignment helpers at extreme scales ------------------------------------------------
@pytest.mark.parametrize("scale", [1e-100, 1e-3, 1.0, 1e3, 1e100])
def test_alignment_recovers_a_transform_at_any_scale(scale):
    from robolab.evaluation import align_points

    pts = np.random.default_rng(0).normal(size=(30, 2)) * scale
    pose = np.array([0.7 * scale, -0.3 * scale, 2.0])
    est = align_points(pts, transform_points(pts, pose))
    np.testing.assert_allclose(est, pose, rtol=1e-9, atol=1e-12 * scale)


def test_beam_model_hit_mass_skips_erf_only_where_it_is_exactly_one():
    from scipy.special import erf

    x = np.linspace(bm.ERF_IS_ONE, 40.0, 100_001)
    assert np.all(erf(x) == 1.0)  # the premise of evaluating erf only near 0 and z_max
    z_max = 3.0
    z_star = np.linspace(0.0, z_max, 20_001)
    for sigma in (1e-3, 0.05, 0.1, 1.0, 1e3, 1e30):
        s = sigma * np.sqrt(2.0)
        direct = 0.5 * (erf((z_max - z_star) / s) - erf(-z_star / s))
        np.testing.assert_allclose(bm._hit_mass(z_star, z_max, sigma), direct, rtol=1e-15)


@pytest.mark.parametrize("z_max", [1e-300, 1e-3, 3.0, 1e6, 1e300])
@pytest.mark.parametrize("sigma", [1e-300, 1e-20, 1e-3, 0.1, 1.0, 1e3, 1e300, 1.7e308])
def test_beam_model_divides_by_the_hit_mass_only_where_it_is_not_one(z_max, sigma):
    """The mixture's shortcut: outside [lo, hi] the same bits as dividing by _hit_mass,
    inside it the mass is exactly 1 (also at the window's ends and one float past them)."""
    with np.errstate(over="ignore"):  # sigma sqrt 2 overflows for the largest sigma
        lo, hi = bm._erf_window(z_max, sigma)
    rng = np.random.default_rng(0)
    ends = [lo, hi, np.nextafter(lo, -np.inf), np.nextafter(lo, np.inf),
            np.nextafter(hi, -np.inf), np.nextafter(hi, np.inf)]  # fmt: skip
    z_star = np.concatenate(
        [[0.0, z_max, np.nextafter(z_max, 0.0)], np.clip(ends, 0.0, z_max),
         rng.uniform(0.0, z_max, 500), z_max * rng.uniform(0.0, 1e-6, 100),
         z_max * (1.0 - rng.uniform(0.0, 1e-6, 100))]
    )  # fmt: skip
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        mass = bm._hit_mass(z_star, z_max, sigma)
        inside = (z_star >= lo) & (z_star <= hi)
        assert np.all(mass[inside] == 1.0)
        p = rng.uniform(0.0, 5.0, z_star.size)
        got = p.copy()
        bm._divide_by_hit_mass(got, z_star, z_max, sigma, lo, hi, 0.0)
        np.testing.assert_array_equal(got, p / mass)
        # Hit terms skipped below the floor: the same sum once the reading's own terms are
        # added (terms from far below to far above the floor; flat down to subnormal).
        flat = rng.choice([1e-320, 1e-300, 1e-3, 0.04, 1.0, 1e300], z_star.size)
        p = flat * 2.0 ** rng.uniform(-70.0, -40.0, z_star.size)
        got = p.copy()
        bm._divide_by_hit_mass(got, z_star, z_max, sigma, lo, hi, flat * bm.HIT_NEGLIGIBLE)
        np.testing.assert_array_equal(got + flat, p / mass + flat)


def test_beam_model_checks_input_in_the_order_of_its_contract():
    """The min/max shortcut of the input checks raises what the full checks raise: a
    non-finite value before a range error, z before z_star, shapes before ranges."""
    params = {"z_hit": 0.7, "z_short": 0.1, "z_max": 0.1, "z_rand": 0.1,
              "sigma_hit": 0.2, "lambda_short": 0.5, "max_range": 5.0}  # fmt: skip
    ok = np.array([1.0, 2.0])
    cases = [
        ([1.0, np.nan], [9.0, 1.0], "z must be finite"),
        ([1.0, 9.0], [np.inf, 1.0], "z_star must be finite"),
        ([1.0, -np.inf], ok, "z must be finite"),
        ([1.0, 9.0], [1.0, 2.0, 3.0], "same number of beams"),
        ([1.0, 9.0], [9.0, 1.0], "z must lie in"),
        (ok, [-1e-300, 1.0], "z_star must lie in"),
    ]
    for z, z_star, message in cases:
        with pytest.raises(ValueError, match=message):
            bm.beam_range_finder_model(np.array(z), np.array(z_star), params)


@pytest.mark.parametrize("n", [0, 1, 3, 700])
def test_beam_model_blocks_of_poses_agree_with_the_composed_densities(n, monkeypatch):
    """N poses in blocks (also 0 poses, and blocks that do not divide N): the sum of logs of
    the Table 6.1 mixture of the four densities, pose by pose."""
    monkeypatch.setattr(bm, "BLOCK_BEAMS", 7 * 9)  # 7 poses of 9 beams per block
    rng = np.random.default_rng(n)
    params = {"z_hit": 0.8, "z_short": 0.1, "z_max": 0.05, "z_rand": 0.05,
              "sigma_hit": 0.2, "lambda_short": 0.7, "max_range": 4.0}
    z = np.where(rng.random(9) < 0.2, 4.0, rng.uniform(0, 4, 9))
    z_star = rng.uniform(0, 4, (n, 9))
    z_star[:, 0] = 0.0  # touching an obstacle: no p_short
    got = bm.beam_range_finder_model(z, z_star, params, log=True)
    zz = np.broadcast_to(z, z_star.shape)
    mix = (
        0.8 * bm.p_hit(zz, z_star, 4.0, 0.2) + 0.1 * bm.p_short(zz, z_star, 0.7)
        + 0.05 * bm.p_max(zz, 4.0) + 0.05 * bm.p_rand(zz, 4.0)
    )
    assert got.shape == (n,)
    np.testing.assert_allclose(got, np.log(mix).sum(axis=-1), rtol=1e-12)
    np.testing.assert_allclose(
        bm.beam_range_finder_model(z, z_star, params), np.prod(mix, axis=-1), rtol=1e-12
    )
