"""Converts its arguments to float, so Fractions give an inexact float, not Fraction(3, 4).

class: result-type
"""

import numbers


def door_open_posterior(p_z_given_open, p_z_given_closed, p_open):
    for name, value in (
        ("p_z_given_open", p_z_given_open),
        ("p_z_given_closed", p_z_given_closed),
        ("p_open", p_open),
    ):
        if not isinstance(value, numbers.Real) or not 0 <= value <= 1:
            raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")
    lo, lc, prior = float(p_z_given_open), float(p_z_given_closed), float(p_open)
    joint_open = lo * prior
    evidence = joint_open + lc * (1 - prior)
    if evidence == 0:
        raise ValueError("p(z) = 0: the measurement is impossible under both states")
    return joint_open / evidence
