"""Visible checks for the demo lab (the lab that tests the autograder)."""

from __future__ import annotations

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_raises, expect_shape


@check
def check_normalize(normalize) -> None:
    """``normalize([1, 3])`` is ``[0.25, 0.75]``."""
    expect_close("normalize([1, 3])", normalize(np.array([1.0, 3.0])), [0.25, 0.75])
    expect_raises("normalize([1, -1, 2])", ValueError, normalize, np.array([1.0, -1.0, 2.0]))


@check
def check_wrap(wrap) -> None:
    """A quarter turn past a half turn wraps to minus a quarter turn."""
    expect_close("wrap(3*pi/2)", wrap(1.5 * np.pi), -0.5 * np.pi)


@check
def check_mean_pose(mean_pose) -> None:
    """The mean of two poses is a single pose (3,), halfway in x and y."""
    got = expect_shape(
        "mean_pose of two poses", mean_pose(np.array([[0.0, 0.0, 0.2], [2.0, 4.0, 0.2]])), (3,)
    )
    if not np.allclose(got[:2], [1.0, 2.0]):
        raise CheckFailed(
            f"mean_pose: expected x, y = 1, 2 halfway between the poses, got {got[:2]}"
        )
