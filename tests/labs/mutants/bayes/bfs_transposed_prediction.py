"""Predicts with action_model.T @ belief (the [previous, next] convention).

class: formula
"""

import numpy as np

from robolab.validation import as_array, check_probability_vector


def bayes_filter_step(belief, action_model, measurement_likelihood):
    belief = check_probability_vector("belief", belief)
    if belief.ndim != 1:
        raise ValueError("belief must be 1-D")
    n = belief.shape[0]
    action_model = as_array(
        "action_model", action_model, shape=(n, n), finite=True, nonnegative=True
    )
    if not np.allclose(action_model.sum(axis=0), 1.0, atol=1e-9, rtol=0):
        raise ValueError("action_model[x_next, x_prev] must have columns summing to 1")
    likelihood = as_array(
        "measurement_likelihood", measurement_likelihood, shape=(n,), finite=True, nonnegative=True
    )
    predicted = action_model.T @ belief
    corrected = likelihood * predicted
    if not corrected.sum() > 0:
        raise ValueError("p(z) = 0: the corrected belief is zero everywhere")
    return corrected / corrected.sum()
