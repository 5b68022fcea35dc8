r"""Lab 01, Bayes: Bayes' rule, the door problem, and the discrete Bayes filter.

Reference solutions for ``notebooks/01_bayes.ipynb`` (seed 004, part 1;
Probabilistic Robotics, sections 2.3-2.4 and 4.1).

A discrete state ``x`` takes one of ``n`` values ``0 .. n-1``; a belief is a
probability vector of shape ``(n,)``. Bayes' rule (Probabilistic Robotics,
eq. 2.15) in normalized form:

.. math::

    p(x \mid z) = \eta \, p(z \mid x) \, p(x), \qquad
    \eta = \Big(\sum_{x'} p(z \mid x') \, p(x')\Big)^{-1}.
"""

from __future__ import annotations

import numbers

import numpy as np

from robolab.validation import as_array, check_probability_vector

__all__ = ["bayes_posterior", "door_open_posterior", "bayes_filter_step"]

#: Columns of an action model must sum to 1 within this tolerance.
COLUMN_SUM_ATOL = 1e-9


def _relative(likelihood: np.ndarray) -> np.ndarray:
    """``likelihood / max(likelihood)``: the same posterior, with no under- or overflow.

    Only ratios of likelihoods matter; scaling first keeps tiny (subnormal) and huge
    (1e308) likelihoods from rounding to 0 or inf when multiplied and summed.
    """
    top = likelihood.max(initial=0.0)
    return likelihood / top if top > 0 else likelihood


def _normalize(unnormalized: np.ndarray) -> np.ndarray:
    """Divide by the sum (the evidence), refusing a measurement impossible under the belief."""
    evidence = unnormalized.sum()
    if not evidence > 0:
        raise ValueError(
            "the posterior is zero everywhere: the measurement likelihood is 0 in every state "
            "the prior allows, so p(z) = 0 and there is nothing to normalize"
        )
    return unnormalized / evidence


def bayes_posterior(likelihood, prior):
    r"""Posterior of a discrete state after one measurement (Bayes' rule).

    .. math::

        p(x_i \mid z) = \eta \, p(z \mid x_i) \, p(x_i), \qquad
        \eta^{-1} = p(z) = \sum_j p(z \mid x_j) \, p(x_j)

    (Probabilistic Robotics, eq. 2.15, and line 4 of Table 2.1).

    Parameters
    ----------
    likelihood : array_like, shape (n,)
        ``likelihood[i] = p(z | x = i)``: non-negative, finite. It is a function
        of the state, not a distribution over it, so it need not sum to 1.
    prior : array_like, shape (n,)
        ``prior[i] = p(x = i)``: non-negative, sums to 1.

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``p(x = i | z)``: non-negative, sums to 1.

    Raises
    ------
    ValueError
        If ``prior`` is not a probability vector, ``likelihood`` has a negative
        or non-finite entry, the shapes differ or are not 1-D, or ``p(z) = 0``
        (the likelihood is zero wherever the prior is non-zero).
    """
    prior = check_probability_vector("prior", prior)
    if prior.ndim != 1:
        raise ValueError(
            f"prior must be a 1-D probability vector of shape (n,), got shape {prior.shape}"
        )
    likelihood = as_array(
        "likelihood", likelihood, shape=prior.shape, finite=True, nonnegative=True
    )
    return _normalize(_relative(likelihood) * prior)


def _probability(name: str, value):
    """Check one probability: a real number (Fraction kept exact) or an array, all in [0, 1]."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        if not 0 <= value <= 1:  # also False for NaN
            raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")
        return value
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise TypeError(
            f"{name} must be a number or an array of numbers, got {type(value).__name__}"
        )
    arr = as_array(name, value, finite=True)
    if np.any((arr < 0) | (arr > 1)):
        raise ValueError(
            f"{name} must contain probabilities in [0, 1], got range [{arr.min()}, {arr.max()}]"
        )
    return arr


def door_open_posterior(p_z_given_open, p_z_given_closed, p_open):
    r"""Probability that the door is open after a measurement ``z`` (the seed's door problem).

    With the two states open and :math:`\neg` open (closed), Bayes' rule and
    the total probability
    :math:`p(z) = p(z \mid open) p(open) + p(z \mid \neg open) (1 - p(open))` give

    .. math::

        p(open \mid z) = \frac{p(z \mid open) \, p(open)}
                              {p(z \mid open) \, p(open) + p(z \mid \neg open) \, (1 - p(open))}.

    For :math:`p(z \mid open) = 2/3`, :math:`p(z \mid \neg open) = 1/3` and
    :math:`p(open) = 3/5` this is 3/4 (Probabilistic Robotics, section 2.3).

    Parameters
    ----------
    p_z_given_open : float, Fraction or array_like
        :math:`p(z \mid open)`, in [0, 1].
    p_z_given_closed : float, Fraction or array_like
        :math:`p(z \mid \neg open)`, in [0, 1].
    p_open : float, Fraction or array_like
        The prior :math:`p(open)`, in [0, 1].

    Returns
    -------
    float, Fraction or numpy.ndarray
        :math:`p(open \mid z)`. Exact arithmetic is kept: three ``Fraction``
        arguments give a ``Fraction``. Array arguments broadcast.

    Raises
    ------
    ValueError
        If an argument lies outside [0, 1] or is NaN, or if :math:`p(z) = 0`.
    TypeError
        If an argument is not a number.
    """
    lo = _probability("p_z_given_open", p_z_given_open)
    lc = _probability("p_z_given_closed", p_z_given_closed)
    prior = _probability("p_open", p_open)
    joint_open = lo * prior
    evidence = joint_open + lc * (1 - prior)
    if np.any(np.asarray(evidence == 0)):
        raise ValueError(
            "p(z) = 0: the measurement is impossible under both states, so p(open | z) is undefined"
        )
    return joint_open / evidence


def bayes_filter_step(belief, action_model, measurement_likelihood):
    r"""One discrete Bayes filter step: predict with the action, correct with the measurement.

    Probabilistic Robotics, Table 2.1 (the Bayes filter) in its discrete form,
    Table 4.1 (the discrete Bayes filter):

    .. math::

        \overline{bel}(x_t = i) &= \sum_j p(x_t = i \mid u_t, x_{t-1} = j) \, bel(x_{t-1} = j)
            \quad\text{(prediction)} \\
        bel(x_t = i) &= \eta \, p(z_t \mid x_t = i) \, \overline{bel}(x_t = i)
            \quad\text{(correction)}

    In matrix form, :math:`\overline{bel} = A \, bel` and
    :math:`bel' = \eta \, (l \odot \overline{bel})`.

    Parameters
    ----------
    belief : array_like, shape (n,)
        :math:`bel(x_{t-1})`: non-negative, sums to 1.
    action_model : array_like, shape (n, n)
        The action's transition matrix, **indexed [next, previous]**:
        ``action_model[i, j] = p(x_t = i | u_t, x_{t-1} = j)``. Each *column*
        ``action_model[:, j]`` is the distribution of the next state from
        state ``j``, so every column sums to 1. "Do nothing" is the identity.
    measurement_likelihood : array_like, shape (n,)
        ``measurement_likelihood[i] = p(z_t | x_t = i)``: non-negative, finite;
        need not sum to 1.

    Returns
    -------
    numpy.ndarray, shape (n,)
        :math:`bel(x_t)`: non-negative, sums to 1.

    Raises
    ------
    ValueError
        If ``belief`` is not a probability vector, ``action_model`` is not
        ``(n, n)`` with non-negative columns summing to 1, the likelihood is not
        ``(n,)``, non-negative and finite, or the corrected belief is zero
        everywhere (``p(z_t) = 0``).
    """
    belief = check_probability_vector("belief", belief)
    if belief.ndim != 1:
        raise ValueError(
            f"belief must be a 1-D probability vector of shape (n,), got shape {belief.shape}"
        )
    n = belief.shape[0]
    action_model = as_array(
        "action_model", action_model, shape=(n, n), finite=True, nonnegative=True
    )
    col_sums = action_model.sum(axis=0)
    if not np.allclose(col_sums, 1.0, atol=COLUMN_SUM_ATOL, rtol=0):
        raise ValueError(
            "action_model[x_next, x_prev] = p(x_next | u, x_prev) must have columns summing to 1, "
            f"got column sums {np.array2string(col_sums, precision=4)} "
            "(rows summing to 1? a transposed matrix?)"
        )
    likelihood = as_array(
        "measurement_likelihood", measurement_likelihood, shape=(n,), finite=True, nonnegative=True
    )
    predicted = action_model @ belief
    return _normalize(_relative(likelihood) * predicted)
