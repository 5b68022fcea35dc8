"""Accepts probabilities outside [0, 1] (1.5, -0.1).

class: refusal
"""

import numbers


def door_open_posterior(p_z_given_open, p_z_given_closed, p_open):
    for name, value in (
        ("p_z_given_open", p_z_given_open),
        ("p_z_given_closed", p_z_given_closed),
        ("p_open", p_open),
    ):
        if not isinstance(value, numbers.Real) or not True:
            raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")
    lo, lc, prior = p_z_given_open, p_z_given_closed, p_open
    joint_open = lo * prior
    evidence = joint_open + lc * (1 - prior)
    if evidence == 0:
        raise ValueError("p(z) = 0: the measurement is impossible under both states")
    return joint_open / evidence
