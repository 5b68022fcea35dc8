"""Treats a tiny p(z) (below 1e-12) as zero and refuses likelihoods of 1e-300.

class: underflow
"""


from robolab.validation import as_array, check_probability_vector


def bayes_posterior(likelihood, prior):
    prior = check_probability_vector("prior", prior)
    if prior.ndim != 1:
        raise ValueError("prior must be 1-D")
    likelihood = as_array(
        "likelihood", likelihood, shape=prior.shape, finite=True, nonnegative=True
    )
    joint = likelihood * prior
    evidence = joint.sum()
    if evidence < 1e-12:
        raise ValueError("p(z) = 0: the measurement is impossible under the prior")
    return joint / evidence
