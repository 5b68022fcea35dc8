"""Does not check the prior: (0.6, 0.6) or (1.5, -0.5) are used as if they were distributions.

class: refusal
"""

import numpy as np

from robolab.validation import as_array


def bayes_posterior(likelihood, prior):
    prior = np.asarray(prior, dtype=float)
    if prior.ndim != 1:
        raise ValueError("prior must be 1-D")
    likelihood = as_array(
        "likelihood", likelihood, shape=prior.shape, finite=True, nonnegative=True
    )
    joint = likelihood * prior
    evidence = joint.sum()
    if not evidence > 0:
        raise ValueError("p(z) = 0: the measurement is impossible under the prior")
    return joint / evidence
