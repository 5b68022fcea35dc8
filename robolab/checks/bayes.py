"""Visible checks for lab 01, Bayes (``notebooks/01_bayes.ipynb``).

Quick and friendly: a worked example, the shape, one invariant. The hidden
tests check much more (the book's whole door example, bad input, invariants).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_raises, expect_shape

__all__ = ["check_bayes_posterior", "check_door_open_posterior", "check_bayes_filter_step"]


@check
def check_bayes_posterior(bayes_posterior):
    """The door numbers as vectors over (open, closed); a 3-state posterior sums to 1."""
    post = bayes_posterior(np.array([2 / 3, 1 / 3]), np.array([3 / 5, 2 / 5]))
    expect_shape("bayes_posterior(likelihood (2,), prior (2,))", post, (2,))
    expect_close("posterior for likelihood [2/3, 1/3] and prior [3/5, 2/5]", post, [0.75, 0.25])
    post3 = np.asarray(
        bayes_posterior(np.array([0.2, 0.9, 0.4]), np.array([0.5, 0.25, 0.25])), dtype=float
    )
    expect_shape("bayes_posterior with 3 states", post3, (3,))
    if not np.isclose(post3.sum(), 1.0):
        raise CheckFailed(
            f"a posterior must sum to 1; yours sums to {post3.sum():.6g}: did you normalize (eta)?"
        )
    expect_close(
        "posterior for likelihood [0.2, 0.9, 0.4] and prior [0.5, 0.25, 0.25]",
        post3,
        [0.1 / 0.425, 0.225 / 0.425, 0.1 / 0.425],
    )
    expect_raises(
        "bayes_posterior with likelihood [0, 1] and prior [1, 0] (p(z) = 0)",
        ValueError,
        bayes_posterior,
        np.array([0.0, 1.0]),
        np.array([1.0, 0.0]),
    )


@check
def check_door_open_posterior(door_open_posterior):
    """The door problem: p(z|open) = 2/3, p(z|closed) = 1/3, p(open) = 3/5 gives exactly 3/4."""
    p = door_open_posterior(2 / 3, 1 / 3, 3 / 5)
    if np.ndim(p) != 0:
        raise CheckFailed(f"expected a single number, got shape {np.shape(p)}")
    expect_close("door_open_posterior(2/3, 1/3, 3/5)", p, 0.75, atol=1e-12)
    expect_close(
        "door_open_posterior(0.5, 0.5, 0.3) (an uninformative sensor keeps the prior)",
        door_open_posterior(0.5, 0.5, 0.3),
        0.3,
        atol=1e-12,
    )
    exact = door_open_posterior(Fraction(2, 3), Fraction(1, 3), Fraction(3, 5))
    if not isinstance(exact, Fraction) or exact != Fraction(3, 4):
        raise CheckFailed(
            f"door_open_posterior(Fraction(2, 3), Fraction(1, 3), Fraction(3, 5)): expected "
            f"exactly Fraction(3, 4), got {type(exact).__name__} {exact!r}: use plain arithmetic "
            "(*, +, -, /) so that fractions stay exact"
        )
    expect_raises(
        "door_open_posterior(0, 0.2, 1) (p(z) = 0)", ValueError, door_open_posterior, 0.0, 0.2, 1.0
    )


@check
def check_bayes_filter_step(bayes_filter_step):
    """Probabilistic Robotics, section 2.4.2: from 0.5/0.5, do nothing, then sense open."""
    do_nothing = np.eye(2)
    sense_open = np.array([0.6, 0.2])  # p(z = sense_open | open), p(z = sense_open | closed)
    bel = bayes_filter_step(np.array([0.5, 0.5]), do_nothing, sense_open)
    expect_shape("bayes_filter_step(belief (2,), action_model (2, 2), likelihood (2,))", bel, (2,))
    expect_close(
        "bel(X1) after u1 = do nothing, z1 = sense open (book: 0.75, 0.25)", bel, [0.75, 0.25]
    )
    push = np.array([[1.0, 0.8], [0.0, 0.2]])  # push[next, previous]
    bel = bayes_filter_step(np.array([0.0, 1.0]), push, np.ones(2))
    expect_close("a closed door pushed (no measurement information): 0.8 open", bel, [0.8, 0.2])
    expect_raises(
        "bayes_filter_step with the transposed push model (rows, not columns, sum to 1)",
        ValueError,
        bayes_filter_step,
        np.array([0.5, 0.5]),
        push.T,
        np.ones(2),
    )
