"""Hidden tests for lab 01, Bayes (100 points).

Reference values are worked by hand in the comments: the seed's door problem
(3/4) and the door example of Probabilistic Robotics, section 2.4.2. States are
ordered (open, closed) throughout. Action models are indexed
``action_model[x_next, x_prev] = p(x_next | u, x_prev)``.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

grades = pytest.mark.grades

# Probabilistic Robotics, section 2.4.2: the door sensor and the push action.
SENSE_OPEN = np.array([0.6, 0.2])  # p(Z = sense_open | open), p(Z = sense_open | closed)
SENSE_CLOSED = np.array([0.4, 0.8])  # p(Z = sense_closed | open), p(Z = sense_closed | closed)
DO_NOTHING = np.eye(2)  # p(x' | do_nothing, x) = [x' == x]
PUSH = np.array(
    [
        [1.0, 0.8],  # p(open | push, open) = 1,   p(open | push, closed) = 0.8
        [0.0, 0.2],
    ]
)  # p(closed | push, open) = 0, p(closed | push, closed) = 0.2
UNIFORM = np.array([0.5, 0.5])


def _f(x):
    return np.asarray(x, dtype=float)


def _random_simplex(rng, n):
    p = rng.uniform(0.01, 1.0, n)
    return p / p.sum()


def _random_column_stochastic(rng, n):
    a = rng.uniform(0.0, 1.0, (n, n)) ** 3  # skewed, clearly non-symmetric
    return a / a.sum(axis=0, keepdims=True)


# =============================== bayes_posterior (30) ===============================
@grades("bayes_posterior", points=5)
def test_bayes_posterior_reference_values(lab):
    # Seed: (2/3 * 3/5, 1/3 * 2/5) = (2/5, 2/15); sum 8/15 -> (3/4, 1/4).
    np.testing.assert_allclose(
        _f(lab.bayes_posterior([2 / 3, 1 / 3], [3 / 5, 2 / 5])), [0.75, 0.25], atol=1e-12
    )
    # Book, first measurement: (0.6 * 0.5, 0.2 * 0.5) = (0.3, 0.1) -> (0.75, 0.25).
    np.testing.assert_allclose(
        _f(lab.bayes_posterior(SENSE_OPEN, UNIFORM)), [0.75, 0.25], atol=1e-12
    )
    # Three states: (0.1, 0.225, 0.1) / 0.425.
    np.testing.assert_allclose(
        _f(lab.bayes_posterior([0.2, 0.9, 0.4], [0.5, 0.25, 0.25])),
        np.array([0.1, 0.225, 0.1]) / 0.425,
        atol=1e-12,
    )


@grades("bayes_posterior", points=5)
def test_bayes_posterior_matches_brute_force(lab):
    rng = np.random.default_rng(101)
    for n in (1, 2, 5, 64, 1000):
        prior = _random_simplex(rng, n)
        likelihood = rng.uniform(0.0, 3.0, n)  # a likelihood need not sum to 1
        post = _f(lab.bayes_posterior(likelihood, prior))
        assert post.shape == (n,)
        expected = likelihood * prior / np.sum(likelihood * prior)
        np.testing.assert_allclose(post, expected, rtol=1e-10, atol=1e-14)


@grades("bayes_posterior", points=5)
def test_bayes_posterior_invariants(lab):
    rng = np.random.default_rng(102)
    prior = _random_simplex(rng, 7)
    # An uninformative measurement (any constant likelihood) leaves the prior unchanged.
    np.testing.assert_allclose(_f(lab.bayes_posterior(np.ones(7), prior)), prior, atol=1e-12)
    np.testing.assert_allclose(_f(lab.bayes_posterior(np.full(7, 0.3), prior)), prior, atol=1e-12)
    # A state with prior 0 stays at 0 whatever the likelihood; the rest is normalized.
    prior0 = prior.copy()
    prior0[[1, 4]] = 0.0
    prior0 /= prior0.sum()
    post = _f(lab.bayes_posterior(rng.uniform(0.1, 1.0, 7), prior0))
    assert post[1] == 0.0 and post[4] == 0.0
    assert np.all(post >= 0) and post.sum() == pytest.approx(1.0, abs=1e-12)


@grades("bayes_posterior", points=3)
def test_bayes_posterior_tiny_likelihoods_no_nan(lab):
    # Likelihoods of 1e-300 are valid; the answer is the same as for (1, 3): (1/4, 3/4).
    post = _f(lab.bayes_posterior([1e-300, 3e-300], UNIFORM))
    assert np.all(np.isfinite(post))
    np.testing.assert_allclose(post, [0.25, 0.75], rtol=1e-9)
    # A likelihood that is zero for some states is fine as long as p(z) > 0.
    np.testing.assert_allclose(
        _f(lab.bayes_posterior([0.0, 0.5, 0.0], [0.2, 0.3, 0.5])), [0.0, 1.0, 0.0]
    )


@grades("bayes_posterior", points=3)
def test_bayes_posterior_rejects_prior_not_summing_to_one(lab):
    with pytest.raises(ValueError):
        lab.bayes_posterior([0.5, 0.5], [0.6, 0.6])
    with pytest.raises(ValueError):
        lab.bayes_posterior([0.5, 0.5], [1.5, -0.5])  # sums to 1 but is not a distribution


@grades("bayes_posterior", points=3)
def test_bayes_posterior_rejects_negative_likelihood(lab):
    with pytest.raises(ValueError):
        lab.bayes_posterior([0.6, -0.2], UNIFORM)


@grades("bayes_posterior", points=3)
def test_bayes_posterior_rejects_mismatched_shapes(lab):
    with pytest.raises(ValueError):
        lab.bayes_posterior([0.6, 0.2, 0.1], UNIFORM)
    with pytest.raises(ValueError):
        lab.bayes_posterior([0.6], UNIFORM)


@grades("bayes_posterior", points=3)
def test_bayes_posterior_rejects_impossible_measurement(lab):
    # The likelihood is zero exactly where the prior is non-zero: p(z) = 0, so no posterior
    # exists (0 / 0); the function must say so instead of returning NaN.
    with pytest.raises(ValueError):
        lab.bayes_posterior([0.0, 1.0], [1.0, 0.0])
    with pytest.raises(ValueError):
        lab.bayes_posterior([0.0, 0.0, 0.0], [0.2, 0.3, 0.5])


# ============================= door_open_posterior (25) =============================
@grades("door_open_posterior", points=6)
def test_door_open_posterior_seed_value(lab):
    # (2/3 * 3/5) / (2/3 * 3/5 + 1/3 * 2/5) = (2/5) / (2/5 + 2/15) = (6/15) / (8/15) = 3/4.
    assert float(lab.door_open_posterior(2 / 3, 1 / 3, 3 / 5)) == pytest.approx(0.75, abs=1e-12)


@grades("door_open_posterior", points=6)
def test_door_open_posterior_exact_with_fractions(lab):
    result = lab.door_open_posterior(Fraction(2, 3), Fraction(1, 3), Fraction(3, 5))
    assert isinstance(result, Fraction), f"expected a Fraction, got {type(result).__name__}"
    assert result == Fraction(3, 4)
    # The book's first step as fractions: (3/5 * 1/2) / (3/5 * 1/2 + 1/5 * 1/2) = 3/4 too.
    assert lab.door_open_posterior(Fraction(3, 5), Fraction(1, 5), Fraction(1, 2)) == Fraction(3, 4)


@grades("door_open_posterior", points=5)
def test_door_open_posterior_matches_formula(lab):
    rng = np.random.default_rng(103)
    for lo, lc, p in rng.uniform(0.01, 1.0, (25, 3)):
        expected = lo * p / (lo * p + lc * (1 - p))
        assert float(lab.door_open_posterior(float(lo), float(lc), float(p))) == pytest.approx(
            expected, rel=1e-10
        )


@grades("door_open_posterior", points=4)
def test_door_open_posterior_special_cases(lab):
    # An uninformative sensor (same likelihood for both states) returns the prior.
    assert float(lab.door_open_posterior(0.3, 0.3, 0.7)) == pytest.approx(0.7, abs=1e-12)
    # Certain priors stay certain; a sensor that never fires for a closed door proves it open.
    assert float(lab.door_open_posterior(0.6, 0.2, 0.0)) == pytest.approx(0.0, abs=1e-15)
    assert float(lab.door_open_posterior(0.6, 0.2, 1.0)) == pytest.approx(1.0, abs=1e-15)
    assert float(lab.door_open_posterior(0.6, 0.0, 0.1)) == pytest.approx(1.0, abs=1e-15)


@grades("door_open_posterior", points=4)
def test_door_open_posterior_rejects_bad_input(lab):
    with pytest.raises(ValueError):
        lab.door_open_posterior(1.5, 0.2, 0.5)  # not a probability
    with pytest.raises(ValueError):
        lab.door_open_posterior(0.6, 0.2, -0.1)  # negative prior
    with pytest.raises(ValueError):
        lab.door_open_posterior(
            0.0, 0.2, 1.0
        )  # p(z) = 0: open is certain but z is impossible when open


# ============================== bayes_filter_step (45) ==============================
@grades("bayes_filter_step", points=6)
def test_filter_book_step_1(lab):
    # u1 = do nothing: bel_bar(X1) = (0.5, 0.5).
    # z1 = sense_open: eta (0.6 * 0.5, 0.2 * 0.5) = eta (0.3, 0.1) = (0.75, 0.25).
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step(UNIFORM, DO_NOTHING, np.ones(2))), UNIFORM, atol=1e-12
    )
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step(UNIFORM, DO_NOTHING, SENSE_OPEN)), [0.75, 0.25], atol=1e-12
    )


@grades("bayes_filter_step", points=8)
def test_filter_book_step_2(lab):
    # u2 = push: bel_bar(X2 = open)   = 1 * 0.75 + 0.8 * 0.25 = 0.95;
    #            bel_bar(X2 = closed) = 0 * 0.75 + 0.2 * 0.25 = 0.05.
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step([0.75, 0.25], PUSH, np.ones(2))), [0.95, 0.05], atol=1e-12
    )
    # z2 = sense_open: eta (0.6 * 0.95, 0.2 * 0.05) = eta (0.57, 0.01)
    #                = (57/58, 1/58) = (0.983, 0.017), the book's bel(X2).
    bel2 = _f(lab.bayes_filter_step([0.75, 0.25], PUSH, SENSE_OPEN))
    np.testing.assert_allclose(bel2, [57 / 58, 1 / 58], atol=1e-12)
    assert round(bel2[0], 3) == 0.983


@grades("bayes_filter_step", points=5)
def test_filter_book_sequence_and_sense_closed(lab):
    bel = UNIFORM
    for u, z, expected in [
        (DO_NOTHING, SENSE_OPEN, [0.75, 0.25]),
        (PUSH, SENSE_OPEN, [57 / 58, 1 / 58]),
    ]:
        bel = _f(lab.bayes_filter_step(bel, u, z))
        np.testing.assert_allclose(bel, expected, atol=1e-12)
    # Had the robot sensed "closed" after the push: eta (0.4 * 0.95, 0.8 * 0.05) = eta (0.38, 0.04)
    # = (19/21, 2/21) = (0.905, 0.095).
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step([0.75, 0.25], PUSH, SENSE_CLOSED)), [19 / 21, 2 / 21], atol=1e-12
    )


@grades("bayes_filter_step", points=5)
def test_filter_uses_next_previous_index_convention(lab):
    # action_model[i, j] = p(x_t = i | u, x_{t-1} = j): the prediction is A @ bel, not A.T @ bel.
    rng = np.random.default_rng(104)
    for n in (3, 6, 40):
        a = _random_column_stochastic(rng, n)
        bel = _random_simplex(rng, n)
        lik = rng.uniform(0.05, 1.0, n)
        predicted = a @ bel
        expected = lik * predicted / np.sum(lik * predicted)
        np.testing.assert_allclose(
            _f(lab.bayes_filter_step(bel, a, lik)), expected, rtol=1e-10, atol=1e-14
        )


@grades("bayes_filter_step", points=6)
def test_filter_invariants(lab):
    rng = np.random.default_rng(105)
    n = 5
    # Doing nothing and learning nothing changes nothing.
    bel = _random_simplex(rng, n)
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step(bel, np.eye(n), np.ones(n))), bel, atol=1e-12
    )
    # A state no action can reach and that starts at zero stays at exactly zero.
    a = _random_column_stochastic(rng, n)
    a[0, :] = 0.0
    a[:, 0] = 0.0
    a[0, 0] = 1.0  # state 0 only leads to itself and nothing leads to it
    a[1:, 1:] /= a[1:, 1:].sum(axis=0, keepdims=True)
    bel = np.r_[0.0, _random_simplex(rng, n - 1)]
    for _ in range(10):
        bel = _f(lab.bayes_filter_step(bel, a, rng.uniform(0.1, 1.0, n)))
        assert bel[0] == 0.0
        assert np.all(bel >= 0) and bel.sum() == pytest.approx(1.0, abs=1e-12)
    # A long random run stays a probability vector.
    bel = np.full(n, 1.0 / n)
    for _ in range(100):
        bel = _f(
            lab.bayes_filter_step(bel, _random_column_stochastic(rng, n), rng.uniform(0.01, 1.0, n))
        )
        assert bel.shape == (n,)
        assert (
            np.all(np.isfinite(bel))
            and np.all(bel >= 0)
            and bel.sum() == pytest.approx(1.0, abs=1e-9)
        )


@grades("bayes_filter_step", points=5)
def test_filter_cyclic_corridor(lab):
    # A robot in a cyclic corridor of 10 cells moves one cell right per step with certainty:
    # the action model is a cyclic shift, A[i, j] = 1 if i = j + 1 (mod 10).
    n = 10
    shift = np.roll(np.eye(n), 1, axis=0)
    bel = np.zeros(n)
    bel[3] = 1.0
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step(bel, shift, np.ones(n))), np.roll(bel, 1), atol=1e-15
    )
    # Doors at cells 0, 3 and 7; the sensor says "door" with p 0.9 at a door and 0.1 elsewhere.
    # From a uniform belief, sensing a door after the move leaves 3 equal peaks:
    # 0.9 / (3 * 0.9 + 7 * 0.1) = 0.9 / 3.4 at the doors, 0.1 / 3.4 elsewhere.
    door = np.full(n, 0.1)
    door[[0, 3, 7]] = 0.9
    bel = _f(lab.bayes_filter_step(np.full(n, 0.1), shift, door))
    np.testing.assert_allclose(bel[[0, 3, 7]], 0.9 / 3.4, atol=1e-12)
    np.testing.assert_allclose(np.delete(bel, [0, 3, 7]), 0.1 / 3.4, atol=1e-12)


@grades("bayes_filter_step", points=2)
def test_filter_rejects_bad_belief(lab):
    with pytest.raises(ValueError):
        lab.bayes_filter_step([0.7, 0.7], DO_NOTHING, SENSE_OPEN)
    with pytest.raises(ValueError):
        lab.bayes_filter_step([1.2, -0.2], DO_NOTHING, SENSE_OPEN)


@grades("bayes_filter_step", points=3)
def test_filter_rejects_action_model_whose_columns_do_not_sum_to_one(lab):
    # The transposed push model has rows, not columns, summing to 1 (column sums 1.8 and 0.2).
    with pytest.raises(ValueError):
        lab.bayes_filter_step([0.75, 0.25], PUSH.T, SENSE_OPEN)
    with pytest.raises(ValueError):  # columns sum to 1 but an entry is negative
        lab.bayes_filter_step([0.75, 0.25], [[1.2, 0.0], [-0.2, 1.0]], SENSE_OPEN)


@grades("bayes_filter_step", points=2)
def test_filter_rejects_negative_likelihood(lab):
    with pytest.raises(ValueError):
        lab.bayes_filter_step([0.75, 0.25], PUSH, [0.6, -0.2])


@grades("bayes_filter_step", points=2)
def test_filter_rejects_mismatched_shapes(lab):
    with pytest.raises(ValueError):
        lab.bayes_filter_step(UNIFORM, np.eye(3), SENSE_OPEN)
    with pytest.raises(ValueError):
        lab.bayes_filter_step(UNIFORM, DO_NOTHING, [0.6, 0.2, 0.1])
    with pytest.raises(ValueError):
        lab.bayes_filter_step(UNIFORM, np.ones((2, 3)) / 2, SENSE_OPEN)


@grades("bayes_filter_step", points=1)
def test_filter_rejects_impossible_measurement(lab):
    # After the push the door is open for sure (bel_bar = (1, 0)); a sensor that never reports
    # this z for an open door makes p(z) = 0.
    with pytest.raises(ValueError):
        lab.bayes_filter_step([1.0, 0.0], PUSH, [0.0, 0.8])
