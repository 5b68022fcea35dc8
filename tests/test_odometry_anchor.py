"""Raw odometry in the map frame: ``compose(truth0, relative(odom0, odom))``.

``compose(truth0, odom)`` is right only when odometry starts at the origin; real
odometry starts anywhere. Oracles: a perfect odometry (the true path seen from an
arbitrary odometry frame) must anchor onto the true path exactly, and on the real
Olin bag the robot stands still for 15 s, so anchored odometry must stay on the
first true pose while the shortcut is off by the odometry's start pose.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robolab.geometry import anchor_odometry, angle_diff, compose, inverse, relative

OLIN = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "olin_ac109_1"


@pytest.mark.parametrize("seed", range(5))
def test_perfect_odometry_from_any_start_anchors_onto_the_truth(seed):
    rng = np.random.default_rng(seed)
    steps = np.column_stack(
        [rng.uniform(0, 0.2, 50), rng.normal(0, 0.05, 50), rng.normal(0, 0.2, 50)]
    )
    truth = [rng.uniform(-5, 5, 3)]
    for s in steps:
        truth.append(compose(truth[-1], s))
    truth = np.array(truth)
    odom_frame = rng.uniform(-10, 10, 3)  # where the odometry frame happens to sit in the map
    odom = compose(inverse(odom_frame), truth)  # the same path in the odometry frame
    anchored = anchor_odometry(odom, truth[0])
    np.testing.assert_allclose(anchored[:, :2], truth[:, :2], atol=1e-9)
    np.testing.assert_allclose(angle_diff(anchored[:, 2], truth[:, 2]), 0, atol=1e-9)
    # the shortcut is wrong unless the odometry frame is the map frame
    assert np.abs(compose(truth[0], odom) - truth)[:, :2].max() > 0.1
    # odom_start at another time: anchor at that time's true pose
    np.testing.assert_allclose(
        anchor_odometry(odom, truth[10], odom[10])[:, :2], truth[:, :2], atol=1e-9
    )
    # a single pose works too
    np.testing.assert_allclose(anchor_odometry(odom[3], truth[0], odom[0]), truth[3], atol=1e-9)


def test_anchor_odometry_checks_its_arguments():
    with pytest.raises(ValueError, match="odom_poses"):
        anchor_odometry(np.zeros((4, 2)), np.zeros(3))
    with pytest.raises(ValueError, match="start_pose"):
        anchor_odometry(np.zeros((4, 3)), [0.0, np.nan, 0.0])


@pytest.mark.skipif(not OLIN.is_dir(), reason="../shared/data/olin_ac109_1 not present")
def test_real_bag_odometry_anchors_without_phantom_drift():
    from robolab.datasets import read_recording

    rec = read_recording(OLIN / "ac109_1_demo.bag", scan_topic="/scan", truth="/map_pose")
    t = rec.scans.stamps - rec.scans.stamps[0]
    still = t < 12.0  # the robot stands still for the first ~15 s
    anchored = anchor_odometry(rec.odom, rec.truth[0])
    err = np.hypot(*(anchored[still, :2] - rec.truth[still, :2]).T)
    assert err.max() < 0.05
    shortcut = compose(rec.truth[0], rec.odom)
    assert abs(rec.odom[0, 2]) > 0.2  # this bag's odometry does not start at theta = 0
    assert abs(angle_diff(shortcut[0, 2], rec.truth[0, 2])) > 0.2
    # while driving, anchored odometry follows the motion: its relative steps are odometry's
    np.testing.assert_allclose(
        relative(anchored[:-1], anchored[1:]), relative(rec.odom[:-1], rec.odom[1:]), atol=1e-9
    )
