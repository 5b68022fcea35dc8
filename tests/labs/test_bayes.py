"""Hidden tests for lab 01, Bayes (100 points).

Reference values are worked by hand in the comments: the seed's door problem
(3/4) and the door example of Probabilistic Robotics, section 2.4.2. States are
ordered (open, closed) throughout. Action models are indexed
``action_model[x_next, x_prev] = p(x_next | u, x_prev)``.

Refusal tests pay only when the function computes the right values too
(``requires``); a student's ``bayes_filter_step`` may call their
``bayes_posterior``, so its failures point there when that one is wrong (``USES``).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

grades = pytest.mark.grades
requires = pytest.mark.requires

#: CPU seconds the reference solution's worker uses while graded (loading and every call,
#: children included: `cpu_seconds` of the correct example in `make grade`'s gradebook.json,
#: 2026-12-02): a submission gets 8 times that in total, at least 20 s (docs/grading.md).
REFERENCE_CPU_SECONDS = 0.25

#: A student's filter step may correct with their own bayes_posterior.
USES = {"bayes_filter_step": ["bayes_posterior"]}

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
@grades("bayes_posterior", points=6)
def test_bayes_posterior_reference_values(lab):
    """bayes_posterior: the door example (3/4, 1/4), the book's first step, and three states."""
    # Seed: (2/3 * 3/5, 1/3 * 2/5) = (2/5, 2/15); sum 8/15 -> (3/4, 1/4).
    np.testing.assert_allclose(
        _f(lab.bayes_posterior([2 / 3, 1 / 3], [3 / 5, 2 / 5])),
        [0.75, 0.25],
        atol=1e-12,
        err_msg="likelihood (2/3, 1/3), prior (3/5, 2/5): expected (2/5, 2/15) / (8/15) = "
        "(3/4, 1/4)",
    )
    # Book, first measurement: (0.6 * 0.5, 0.2 * 0.5) = (0.3, 0.1) -> (0.75, 0.25).
    np.testing.assert_allclose(
        _f(lab.bayes_posterior(SENSE_OPEN, UNIFORM)),
        [0.75, 0.25],
        atol=1e-12,
        err_msg="likelihood (0.6, 0.2), prior (0.5, 0.5): expected (0.3, 0.1) / 0.4 = (0.75, 0.25)",
    )
    np.testing.assert_allclose(
        _f(lab.bayes_posterior([0.2, 0.9, 0.4], [0.5, 0.25, 0.25])),
        np.array([0.1, 0.225, 0.1]) / 0.425,
        atol=1e-12,
        err_msg="likelihood (0.2, 0.9, 0.4), prior (0.5, 0.25, 0.25): expected "
        "(0.1, 0.225, 0.1) / 0.425",
    )


@grades("bayes_posterior", points=6)
def test_bayes_posterior_matches_brute_force(lab):
    """bayes_posterior: random priors (far from uniform) and likelihoods of 1 to 1000 states."""
    rng = np.random.default_rng(101)
    for n in (1, 2, 5, 64, 1000):
        prior = _random_simplex(rng, n)
        likelihood = rng.uniform(0.0, 3.0, n)  # a likelihood need not sum to 1
        post = _f(lab.bayes_posterior(likelihood, prior))
        assert post.shape == (n,), f"{n} states: expected shape ({n},), got {post.shape}"
        expected = likelihood * prior / np.sum(likelihood * prior)
        np.testing.assert_allclose(
            post,
            expected,
            rtol=1e-10,
            atol=1e-14,
            err_msg=f"{n} states, a random prior and likelihood: expected likelihood * prior "
            "divided by its sum",
        )


@grades("bayes_posterior", points=5)
def test_bayes_posterior_invariants(lab):
    """bayes_posterior: a constant likelihood keeps the prior; a state of prior 0 stays at 0."""
    rng = np.random.default_rng(102)
    prior = _random_simplex(rng, 7)
    for c in (1.0, 0.3):
        np.testing.assert_allclose(
            _f(lab.bayes_posterior(np.full(7, c), prior)),
            prior,
            atol=1e-12,
            err_msg=f"a constant likelihood ({c}) tells nothing: expected the prior unchanged",
        )
    prior0 = prior.copy()
    prior0[[1, 4]] = 0.0
    prior0 /= prior0.sum()
    post = _f(lab.bayes_posterior(rng.uniform(0.1, 1.0, 7), prior0))
    assert post[1] == 0.0 and post[4] == 0.0, (
        f"states 1 and 4 have prior 0: expected posterior 0 there, got {post[1]!r}, {post[4]!r}"
    )
    assert np.all(post >= 0) and post.sum() == pytest.approx(1.0, abs=1e-12), (
        f"7 states: expected a probability vector, got sum {post.sum()!r}, min {post.min()!r}"
    )


@grades("bayes_posterior", points=4)
def test_bayes_posterior_tiny_likelihoods_no_nan(lab):
    """bayes_posterior: likelihoods of 1e-300 are valid, and zero likelihoods in some states too."""
    post = _f(lab.bayes_posterior([1e-300, 3e-300], UNIFORM))
    np.testing.assert_allclose(
        post,
        [0.25, 0.75],
        rtol=1e-9,
        err_msg="likelihood (1e-300, 3e-300), uniform prior: a tiny p(z) is not p(z) = 0; "
        "expected (1/4, 3/4) as for (1, 3)",
    )
    np.testing.assert_allclose(
        _f(lab.bayes_posterior([0.0, 0.5, 0.0], [0.2, 0.3, 0.5])),
        [0.0, 1.0, 0.0],
        atol=1e-15,
        err_msg="likelihood (0, 0.5, 0), prior (0.2, 0.3, 0.5): expected (0, 1, 0)",
    )


POSTERIOR_VALUES = (
    "test_bayes_posterior_reference_values",
    "test_bayes_posterior_matches_brute_force",
)


@grades("bayes_posterior", points=2)
@requires(*POSTERIOR_VALUES)
def test_bayes_posterior_rejects_prior_not_summing_to_one(lab, refuses):
    """bayes_posterior: a prior (0.6, 0.6), or (1.5, -0.5), is no distribution: ValueError."""
    with refuses(ValueError, "prior = (0.6, 0.6), which sums to 1.2"):
        lab.bayes_posterior([0.5, 0.5], [0.6, 0.6])
    with refuses(ValueError, "prior = (1.5, -0.5), which sums to 1 but has a negative entry"):
        lab.bayes_posterior([0.5, 0.5], [1.5, -0.5])  # sums to 1 but is not a distribution


@grades("bayes_posterior", points=2)
@requires(*POSTERIOR_VALUES)
def test_bayes_posterior_rejects_negative_likelihood(lab, refuses):
    """bayes_posterior: a negative likelihood (0.6, -0.2) raises ValueError."""
    with refuses(ValueError, "likelihood = (0.6, -0.2), a negative likelihood"):
        lab.bayes_posterior([0.6, -0.2], UNIFORM)


@grades("bayes_posterior", points=2)
@requires(*POSTERIOR_VALUES)
def test_bayes_posterior_rejects_mismatched_shapes(lab, refuses):
    """bayes_posterior: a likelihood of 3 or 1 states for a prior of 2 raises ValueError."""
    with refuses(ValueError, "likelihood of 3 states (0.6, 0.2, 0.1) for a prior of 2"):
        lab.bayes_posterior([0.6, 0.2, 0.1], UNIFORM)
    with refuses(ValueError, "likelihood of 1 state (0.6,) for a prior of 2"):
        lab.bayes_posterior([0.6], UNIFORM)


@grades("bayes_posterior", points=3)
@requires(*POSTERIOR_VALUES)
def test_bayes_posterior_rejects_impossible_measurement(lab, refuses):
    """bayes_posterior: p(z) = 0 (likelihood 0 wherever the prior is not) raises, no NaN."""
    with refuses(
        ValueError, "likelihood = (0, 1) with prior = (1, 0): p(z) = 0, an impossible measurement"
    ):
        lab.bayes_posterior([0.0, 1.0], [1.0, 0.0])
    with refuses(ValueError, "likelihood = (0, 0, 0): p(z) = 0, an impossible measurement"):
        lab.bayes_posterior([0.0, 0.0, 0.0], [0.2, 0.3, 0.5])


# ============================= door_open_posterior (25) =============================
@grades("door_open_posterior", points=6)
def test_door_open_posterior_seed_value(lab):
    """door_open_posterior: p(z|open) = 2/3, p(z|closed) = 1/3, p(open) = 3/5 gives 3/4."""
    got = float(lab.door_open_posterior(2 / 3, 1 / 3, 3 / 5))
    assert got == pytest.approx(0.75, abs=1e-12), (
        f"door_open_posterior(2/3, 1/3, 3/5): expected (2/5) / (2/5 + 2/15) = 3/4, got {got!r}"
    )


@grades("door_open_posterior", points=6)
def test_door_open_posterior_exact_with_fractions(lab):
    """door_open_posterior: Fraction arguments give exactly Fraction(3, 4), not a float."""
    result = lab.door_open_posterior(Fraction(2, 3), Fraction(1, 3), Fraction(3, 5))
    assert isinstance(result, Fraction), (
        f"door_open_posterior(Fraction(2, 3), Fraction(1, 3), Fraction(3, 5)): expected a "
        f"Fraction (plain arithmetic keeps it exact), got {type(result).__name__} {result!r}"
    )
    assert result == Fraction(3, 4), (
        f"door_open_posterior(Fraction(2, 3), Fraction(1, 3), Fraction(3, 5)): expected "
        f"Fraction(3, 4), got {result!r}"
    )
    got = lab.door_open_posterior(Fraction(3, 5), Fraction(1, 5), Fraction(1, 2))
    assert got == Fraction(3, 4), (
        f"door_open_posterior(Fraction(3, 5), Fraction(1, 5), Fraction(1, 2)): expected "
        f"(3/10) / (3/10 + 1/10) = Fraction(3, 4), got {got!r}"
    )


@grades("door_open_posterior", points=5)
def test_door_open_posterior_matches_formula(lab):
    """door_open_posterior: 25 random triples give p(z|o) p(o) / (p(z|o) p(o) + p(z|c) p(c))."""
    rng = np.random.default_rng(103)
    for lo, lc, p in rng.uniform(0.01, 1.0, (25, 3)):
        expected = lo * p / (lo * p + lc * (1 - p))
        got = float(lab.door_open_posterior(float(lo), float(lc), float(p)))
        assert got == pytest.approx(expected, rel=1e-10), (
            f"door_open_posterior({lo:.4f}, {lc:.4f}, {p:.4f}): expected {expected!r}, got {got!r}"
        )


@grades("door_open_posterior", points=4)
def test_door_open_posterior_special_cases(lab):
    """door_open_posterior: an uninformative sensor keeps the prior; priors 0 and 1 are valid."""
    for args, expected in [
        ((0.3, 0.3, 0.7), 0.7),  # the same likelihood for both states
        ((0.6, 0.2, 0.0), 0.0),  # the door is surely closed
        ((0.6, 0.2, 1.0), 1.0),  # the door is surely open
        ((0.6, 0.0, 0.1), 1.0),  # the sensor never fires for a closed door
    ]:
        got = float(lab.door_open_posterior(*args))
        assert got == pytest.approx(expected, abs=1e-12), (
            f"door_open_posterior{args}: expected {expected}, got {got!r}"
        )


DOOR_VALUES = ("test_door_open_posterior_seed_value", "test_door_open_posterior_matches_formula")


@grades("door_open_posterior", points=2)
@requires(*DOOR_VALUES)
def test_door_open_posterior_rejects_bad_input(lab, refuses):
    """door_open_posterior: a likelihood of 1.5 or a prior of -0.1 raises ValueError."""
    with refuses(ValueError, "p_z_given_open = 1.5, not a probability"):
        lab.door_open_posterior(1.5, 0.2, 0.5)  # not a probability
    with refuses(ValueError, "p_open = -0.1, a negative prior"):
        lab.door_open_posterior(0.6, 0.2, -0.1)  # negative prior


@grades("door_open_posterior", points=2)
@requires(*DOOR_VALUES)
def test_door_open_posterior_rejects_impossible_measurement(lab, refuses):
    """door_open_posterior: open is certain but z is impossible when open: p(z) = 0, ValueError."""
    with refuses(
        ValueError, "p_z_given_open = 0 with p_open = 1: p(z) = 0, an impossible measurement"
    ):
        lab.door_open_posterior(0.0, 0.2, 1.0)
    with refuses(ValueError, "p_z_given_open = p_z_given_closed = 0 (as Fractions): p(z) = 0"):
        lab.door_open_posterior(Fraction(0), Fraction(0), Fraction(1, 2))


# ============================== bayes_filter_step (45) ==============================
@grades("bayes_filter_step", points=6)
def test_filter_book_step_1(lab):
    """bayes_filter_step: the book's step 1, do nothing then sense open, gives (0.75, 0.25)."""
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step(UNIFORM, DO_NOTHING, np.ones(2))),
        UNIFORM,
        atol=1e-12,
        err_msg="from (0.5, 0.5), do nothing, no information: expected (0.5, 0.5)",
    )
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step(UNIFORM, DO_NOTHING, SENSE_OPEN)),
        [0.75, 0.25],
        atol=1e-12,
        err_msg="from (0.5, 0.5), do nothing, sense open (0.6, 0.2): expected eta (0.3, 0.1) = "
        "(0.75, 0.25)",
    )


@grades("bayes_filter_step", points=8)
def test_filter_book_step_2(lab):
    """bayes_filter_step: the book's step 2, push then sense open, gives (0.983, 0.017)."""
    # bel_bar(open) = 1 * 0.75 + 0.8 * 0.25 = 0.95; bel_bar(closed) = 0.2 * 0.25 = 0.05.
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step([0.75, 0.25], PUSH, np.ones(2))),
        [0.95, 0.05],
        atol=1e-12,
        err_msg="from (0.75, 0.25), push, no information: expected the prediction "
        "(1 * 0.75 + 0.8 * 0.25, 0.2 * 0.25) = (0.95, 0.05)",
    )
    bel2 = _f(lab.bayes_filter_step([0.75, 0.25], PUSH, SENSE_OPEN))
    np.testing.assert_allclose(
        bel2,
        [57 / 58, 1 / 58],
        atol=1e-12,
        err_msg="from (0.75, 0.25), push, sense open: expected eta (0.6 * 0.95, 0.2 * 0.05) = "
        "(57/58, 1/58), the book's (0.983, 0.017)",
    )


@grades("bayes_filter_step", points=5)
def test_filter_book_sequence_and_sense_closed(lab):
    """bayes_filter_step: the two book steps in a row, and sensing closed after the push."""
    bel = UNIFORM
    for step, (u, z, expected) in enumerate(
        [(DO_NOTHING, SENSE_OPEN, [0.75, 0.25]), (PUSH, SENSE_OPEN, [57 / 58, 1 / 58])], 1
    ):
        bel = _f(lab.bayes_filter_step(bel, u, z))
        np.testing.assert_allclose(
            bel,
            expected,
            atol=1e-12,
            err_msg=f"the book's sequence, step {step}: expected {np.round(expected, 4)}",
        )
    # eta (0.4 * 0.95, 0.8 * 0.05) = eta (0.38, 0.04) = (19/21, 2/21).
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step([0.75, 0.25], PUSH, SENSE_CLOSED)),
        [19 / 21, 2 / 21],
        atol=1e-12,
        err_msg="from (0.75, 0.25), push, sense closed (0.4, 0.8): expected eta (0.38, 0.04) = "
        "(19/21, 2/21)",
    )


@grades("bayes_filter_step", points=6)
def test_filter_uses_next_previous_index_convention(lab):
    """bayes_filter_step: random skewed action models A[next, previous]: predict with A @ bel."""
    rng = np.random.default_rng(104)
    for n in (3, 6, 40):
        a = _random_column_stochastic(rng, n)
        bel = _random_simplex(rng, n)
        lik = rng.uniform(0.05, 1.0, n)
        predicted = a @ bel
        expected = lik * predicted / np.sum(lik * predicted)
        np.testing.assert_allclose(
            _f(lab.bayes_filter_step(bel, a, lik)),
            expected,
            rtol=1e-10,
            atol=1e-14,
            err_msg=f"{n} states, a random action model indexed [next, previous]: expected "
            "eta * likelihood * (A @ belief) (A.T @ belief is the transposed convention)",
        )


@grades("bayes_filter_step", points=5)
@requires("test_filter_book_step_2")
def test_filter_invariants(lab):
    """bayes_filter_step: nothing done and learnt changes nothing; unreachable states stay 0.

    The smallest world, one state, is certain: its belief stays (1,), an array of one.
    """
    one = _f(lab.bayes_filter_step([1.0], [[1.0]], [0.3]))
    assert one.shape == (1,) and one[0] == pytest.approx(1.0, abs=1e-12), (
        f"one state: belief (1,), action [[1]], likelihood (0.3,): expected the belief [1.0] "
        f"of shape (1,), got {one!r}"
    )
    rng = np.random.default_rng(105)
    n = 5
    bel = _random_simplex(rng, n)
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step(bel, np.eye(n), np.ones(n))),
        bel,
        atol=1e-12,
        err_msg="the identity action and a constant likelihood: expected the belief unchanged",
    )
    a = _random_column_stochastic(rng, n)
    a[0, :] = 0.0
    a[:, 0] = 0.0
    a[0, 0] = 1.0  # state 0 only leads to itself and nothing leads to it
    a[1:, 1:] /= a[1:, 1:].sum(axis=0, keepdims=True)
    bel = np.r_[0.0, _random_simplex(rng, n - 1)]
    for step in range(10):
        bel = _f(lab.bayes_filter_step(bel, a, rng.uniform(0.1, 1.0, n)))
        assert bel[0] == 0.0, (
            f"step {step}: state 0 starts at 0 and nothing leads to it: expected 0, got {bel[0]!r}"
        )
        assert np.all(bel >= 0) and bel.sum() == pytest.approx(1.0, abs=1e-12), (
            f"step {step}: expected a probability vector, got {bel}"
        )
    bel = np.full(n, 1.0 / n)
    for step in range(100):
        bel = _f(
            lab.bayes_filter_step(bel, _random_column_stochastic(rng, n), rng.uniform(0.01, 1.0, n))
        )
        ok = bel.shape == (n,) and np.all(np.isfinite(bel)) and np.all(bel >= 0)
        assert ok and bel.sum() == pytest.approx(1.0, abs=1e-9), (
            f"step {step} of a 100-step random run: expected a probability vector of shape "
            f"({n},), got {bel}"
        )


@grades("bayes_filter_step", points=5)
def test_filter_cyclic_corridor(lab):
    """bayes_filter_step: a cyclic corridor, one cell right per step, doors at cells 0, 3, 7."""
    n = 10
    shift = np.roll(np.eye(n), 1, axis=0)  # A[i, j] = 1 if i = j + 1 (mod 10)
    bel = np.zeros(n)
    bel[3] = 1.0
    np.testing.assert_allclose(
        _f(lab.bayes_filter_step(bel, shift, np.ones(n))),
        np.roll(bel, 1),
        atol=1e-15,
        err_msg="certain at cell 3, move one cell right: expected certain at cell 4",
    )
    door = np.full(n, 0.1)
    door[[0, 3, 7]] = 0.9
    bel = _f(lab.bayes_filter_step(np.full(n, 0.1), shift, door))
    np.testing.assert_allclose(
        bel[[0, 3, 7]],
        0.9 / 3.4,
        atol=1e-12,
        err_msg="uniform, move, sense a door (0.9 at doors, 0.1 elsewhere): expected "
        "0.9 / (3 * 0.9 + 7 * 0.1) = 0.265 at the doors",
    )
    np.testing.assert_allclose(
        np.delete(bel, [0, 3, 7]),
        0.1 / 3.4,
        atol=1e-12,
        err_msg="uniform, move, sense a door: expected 0.1 / 3.4 = 0.029 away from the doors",
    )


FILTER_VALUES = ("test_filter_book_step_2", "test_filter_uses_next_previous_index_convention")


@grades("bayes_filter_step", points=2)
@requires(*FILTER_VALUES)
def test_filter_rejects_bad_belief(lab, refuses):
    """bayes_filter_step: a belief (0.7, 0.7) or (1.2, -0.2) raises ValueError."""
    with refuses(ValueError, "belief = (0.7, 0.7), which sums to 1.4"):
        lab.bayes_filter_step([0.7, 0.7], DO_NOTHING, SENSE_OPEN)
    with refuses(ValueError, "belief = (1.2, -0.2), which has a negative entry"):
        lab.bayes_filter_step([1.2, -0.2], DO_NOTHING, SENSE_OPEN)


@grades("bayes_filter_step", points=2)
@requires(*FILTER_VALUES)
def test_filter_rejects_action_model_whose_columns_do_not_sum_to_one(lab, refuses):
    """bayes_filter_step: the transposed push model (rows sum to 1) raises ValueError."""
    with refuses(
        ValueError, "action_model = the push model transposed (its columns sum to 1.8 and 0.2)"
    ):
        lab.bayes_filter_step([0.75, 0.25], PUSH.T, SENSE_OPEN)
    with refuses(
        ValueError,
        "action_model = [[1.2, 0], [-0.2, 1]], columns sum to 1 but an entry is negative",
    ):
        lab.bayes_filter_step([0.75, 0.25], [[1.2, 0.0], [-0.2, 1.0]], SENSE_OPEN)


@grades("bayes_filter_step", points=2)
@requires(*FILTER_VALUES)
def test_filter_rejects_negative_likelihood(lab, refuses):
    """bayes_filter_step: a negative likelihood (0.6, -0.2) raises ValueError."""
    with refuses(ValueError, "measurement_likelihood = (0.6, -0.2), a negative likelihood"):
        lab.bayes_filter_step([0.75, 0.25], PUSH, [0.6, -0.2])


@grades("bayes_filter_step", points=2)
@requires(*FILTER_VALUES)
def test_filter_rejects_mismatched_shapes(lab, refuses):
    """bayes_filter_step: a 3 x 3 model, 3 likelihoods or a 2 x 3 model for 2 states: ValueError."""
    with refuses(ValueError, "action_model of shape (3, 3) for a belief of 2 states"):
        lab.bayes_filter_step(UNIFORM, np.eye(3), SENSE_OPEN)
    with refuses(ValueError, "measurement_likelihood of 3 states for a belief of 2"):
        lab.bayes_filter_step(UNIFORM, DO_NOTHING, [0.6, 0.2, 0.1])
    with refuses(ValueError, "action_model of shape (2, 3) for a belief of 2 states"):
        lab.bayes_filter_step(UNIFORM, np.ones((2, 3)) / 2, SENSE_OPEN)


@grades("bayes_filter_step", points=2)
@requires(*FILTER_VALUES)
def test_filter_rejects_impossible_measurement(lab, refuses):
    """bayes_filter_step: after the push the door is surely open; z impossible then: ValueError."""
    with refuses(
        ValueError,
        "measurement_likelihood = (0, 0.8) after the push: p(z) = 0, an impossible measurement",
    ):
        lab.bayes_filter_step([1.0, 0.0], PUSH, [0.0, 0.8])
