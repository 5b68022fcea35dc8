"""Visible checks for lab 00, bags and frames (``notebooks/00_frames.ipynb``).

Quick and friendly: a worked example, the shape, one invariant. The hidden
tests check much more (library oracles, bad input, the bundled bag).
"""

from __future__ import annotations

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_raises, expect_shape

__all__ = ["check_scan_to_cartesian", "check_transform_points", "check_pose_at"]


@check
def check_scan_to_cartesian(scan_to_cartesian):
    """Four beams at 0, 90, 180 and -90 degrees, plus readings that are not returns."""
    ranges = np.array([2.0, 1.0, 3.0, 0.5])
    angles = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2])
    pts = scan_to_cartesian(ranges, angles, 0.1, 10.0)
    expect_shape("scan_to_cartesian with 4 valid beams", pts, (4, 2))
    expect_close(
        "endpoints of ranges [2, 1, 3, 0.5] at 0, 90, 180, -90 degrees",
        pts,
        [[2.0, 0.0], [0.0, 1.0], [-3.0, 0.0], [0.0, -0.5]],
        atol=1e-9,
    )
    bad = np.array([np.inf, 0.0, np.nan, 1.5])
    pts = np.asarray(scan_to_cartesian(bad, np.zeros(4), 0.1, 10.0), dtype=float)
    if pts.shape != (1, 2):
        raise CheckFailed(
            f"ranges [inf, 0, nan, 1.5] hold one real return, so expected shape (1, 2), got "
            f"{pts.shape}: inf, 0 and NaN mean 'no return' and must be dropped"
        )
    expect_close("the one valid beam of [inf, 0, nan, 1.5] at angle 0", pts, [[1.5, 0.0]])
    pts = np.asarray(scan_to_cartesian(np.array([2.0, 10.0]), np.zeros(2), 0.1, 10.0), dtype=float)
    if pts.shape != (1, 2):
        raise CheckFailed(
            f"ranges [2, 10] with range_max 10: expected one return, shape (1, 2), got "
            f"{pts.shape}: a reading of exactly range_max is a max-range reading, not a return"
        )
    expect_raises(
        "scan_to_cartesian with 3 ranges but 2 angles",
        ValueError,
        scan_to_cartesian,
        np.ones(3),
        np.zeros(2),
        0.1,
        10.0,
    )


@check
def check_transform_points(transform_points):
    """A child frame at (1, 2) turned 90 degrees; the identity pose."""
    pts = np.array([[1.0, 0.0], [0.0, 1.0]])
    out = transform_points(pts, np.array([1.0, 2.0, np.pi / 2]))
    expect_shape("transform_points(points (2, 2), pose (3,))", out, (2, 2))
    expect_close(
        "points (1, 0) and (0, 1) of a frame at (1, 2, 90 deg): rotate, then translate",
        out,
        [[1.0, 3.0], [0.0, 2.0]],
        atol=1e-9,
    )
    expect_close(
        "the identity pose (0, 0, 0) changes nothing", transform_points(pts, np.zeros(3)), pts
    )
    expect_shape(
        "transform_points(points (2, 2), poses (4, 3))",
        transform_points(pts, np.zeros((4, 3))),
        (4, 2, 2),
    )
    expect_raises(
        "transform_points with points of shape (2, 3)",
        ValueError,
        transform_points,
        np.ones((2, 3)),
        np.zeros(3),
    )


@check
def check_pose_at(pose_at):
    """Halfway between two poses; across the +-pi seam."""
    stamps = np.array([0.0, 1.0])
    out = pose_at(stamps, np.array([[0.0, 0.0, 0.0], [2.0, 1.0, 1.0]]), 0.5)
    expect_shape("pose_at with a scalar t", out, (3,))
    expect_close("halfway from (0, 0, 0) to (2, 1, 1)", out, [1.0, 0.5, 0.5])
    out = np.asarray(
        pose_at(stamps, np.array([[0.0, 0.0, 3.1], [0.0, 0.0, -3.1]]), 0.5), dtype=float
    )
    if abs((out[2] + np.pi) % (2 * np.pi) - np.pi) < np.pi - 1e-6:
        raise CheckFailed(
            f"halfway from theta = 3.1 to -3.1 rad the heading should be +-pi (the short way "
            f"round, through the seam), got {out[2]:.4f}: interpolate the wrapped difference"
        )
    out = np.asarray(pose_at(stamps, np.zeros((2, 3)), np.array([0.0, 0.3, 1.0])), dtype=float)
    expect_shape("pose_at with 3 times t", out, (3, 3))
    expect_raises(
        "pose_at at t = 2 after the last stamp 1 (no extrapolation)",
        ValueError,
        pose_at,
        stamps,
        np.zeros((2, 3)),
        2.0,
    )
