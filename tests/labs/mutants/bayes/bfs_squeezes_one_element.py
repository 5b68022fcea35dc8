"""Squeezes its result: a belief over one state comes back as a number, not a (1,) array.

The smallest valid input (one particle, beam, pose or state) must keep its axis.

class: minimum-size
"""

import numpy as np

from robolab.validation import as_array, check_probability_vector
from solutions.bayes import COLUMN_SUM_ATOL, _normalize, _relative


def bayes_filter_step(belief, action_model, measurement_likelihood):
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
            f"action_model[x_next, x_prev] = p(x_next | u, x_prev) must have columns summing to 1, got column sums {np.array2string(col_sums, precision=4)} (rows summing to 1? a transposed matrix?)"  # noqa: E501
        )
    likelihood = as_array(
        "measurement_likelihood", measurement_likelihood, shape=(n,), finite=True, nonnegative=True
    )
    predicted = action_model @ belief
    return np.squeeze(_normalize(_relative(likelihood) * predicted))
