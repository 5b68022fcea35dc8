"""The messages that name a mistake's real cause (robolab/checks/base.py).

``where_wrong`` tells a density wrong at single readings (an end of its support, z*)
from one whose normaliser is off; ``angle_error`` prints an angle error as an error,
with the angle got and the angle expected, never as the function's result. Both are
used by the visible checks and the hidden tests alike.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr

from robolab.checks import beam_model as beam_checks
from robolab.checks.base import CheckFailed, angle_error, where_wrong

Z = np.linspace(0.0, 5.0, 2001)


def _p_hit(z, z_star=0.2, z_max=5.0, sigma=0.5):
    eta = 1.0 / (ndtr((z_max - z_star) / sigma) - ndtr(-z_star / sigma))
    inside = (z >= 0) & (z <= z_max)
    return np.where(inside, eta * np.exp(-0.5 * ((z - z_star) / sigma) ** 2), 0.0) / (
        sigma * math.sqrt(2 * math.pi)
    )


MARKS = {"0": 0.0, "z_max": 5.0}


def test_a_right_density_has_nothing_wrong():
    """The same values give None."""
    assert where_wrong(Z, _p_hit(Z), _p_hit(Z), MARKS, "eta") is None, "identical densities"


@pytest.mark.parametrize(
    "drop, named",
    [([0], ["0: at z = 0"]), ([-1], ["z_max: at z = 5"]), ([0, -1], ["0: at z = 0", "z_max"])],
)
def test_an_endpoint_left_out_is_named_not_blamed_on_the_normaliser(drop, named):
    """A density 0 at an end of its support: the message names that end, not eta."""
    got = _p_hit(Z)
    got[drop] = 0.0
    text = where_wrong(Z, got, _p_hit(Z), MARKS, "eta must restore the lost mass")
    assert text is not None and "single readings" in text, f"expected single readings: {text}"
    assert all(n in text for n in named), f"expected {named} named in {text!r}"
    assert "eta" not in text, f"an endpoint mistake must not blame eta: {text!r}"


def test_a_wrong_normaliser_is_a_constant_factor():
    """Every reading off by the same factor: the message is the normaliser's hint."""
    text = where_wrong(Z, 0.5 * _p_hit(Z), _p_hit(Z), MARKS, "eta must restore the lost mass")
    assert text == "off by the same factor 0.5 at every reading: eta must restore the lost mass", (
        text
    )


def test_other_mistakes_show_their_first_wrong_readings():
    """A wrong shape (not a factor, not single points) shows where it starts to differ."""
    got = _p_hit(Z, z_star=0.3)
    text = where_wrong(Z, got, _p_hit(Z), MARKS, "eta")
    assert text is not None and text.startswith("wrong at ") and "e.g. at z = " in text, text


def test_the_visible_check_names_the_endpoint():
    """check_p_hit on a p_hit that excludes z_max says so, and does not blame eta."""

    def open_support(z, z_star, z_max, sigma_hit):
        z = np.asarray(z, dtype=float)
        return np.where(z < z_max, _p_hit(z, z_star, z_max, sigma_hit), 0.0)

    with pytest.raises(CheckFailed) as info:
        beam_checks.check_p_hit(open_support)
    assert "z_max: at z = 5" in str(info.value) and "eta" not in str(info.value), str(info.value)


def test_angle_error_is_named_as_an_error():
    """The largest error, where it is, and the angles got and expected (modulo 2 pi)."""
    assert angle_error([3.1, -3.1], [3.1 - 2 * np.pi, -3.1], 1e-9) is None, "equal modulo 2 pi"
    text = angle_error([0.0, 0.25, 1.0], [0.0, 0.2, 1.0], 1e-9)
    assert text == (
        "the angle error reaches 0.05 rad at index 1 (tolerance 1e-09): got 0.25 rad, "
        "expected 0.2 rad (modulo 2 pi)"
    ), text
    assert "is not a number" in angle_error([np.nan], [0.0], 1e-9), "NaN is named as such"
