"""Hidden tests for lab 06, EKF localization with grid mapping (seed 000, section 4). 100 points.

Every test calls only ``lab.<exercise>(...)`` with plain data (arrays, numbers,
tuples, OccupancyGrids) and compares results after ``np.asarray(..., dtype=float)``,
so it works on the reference solution and, with ``--notebook``, across the
grader's process boundary. Nothing here depends on a student function
mutating its arguments.

Oracles live in this file: the seed's unicycle model written out, finite
differences, a brute-force fine-step ray march, a cell-by-cell transcription
of Probabilistic Robotics Table 9.2 (the seed loops over every cell in the
same way), and an EKF predict + update in plain numpy (Table 3.3).

Points: transition_model 10, state_jacobian 10, measurement_function 15,
measurement_jacobian 10, inverse_sensor_model 15, update_map 10,
ekf_mapping_step 30.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robolab.geometry import wrap_angle
from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays

ANGLES = np.deg2rad(10.0 * np.arange(36))  # the seed's 36 beams
ZMAX = 20.0
#: CPU seconds the reference solution's worker uses while graded (loading and every call,
#: children included: `cpu_seconds` of the correct example in `make grade`'s gradebook.json,
#: 2026-12-02): a submission gets 8 times that in total, at least 20 s (docs/grading.md).
REFERENCE_CPU_SECONDS = 3.7

#: Exercises each exercise is likely to call (the feedback names them when they fail).
USES = {
    "update_map": ["inverse_sensor_model"],
    "ekf_mapping_step": [
        "transition_model",
        "state_jacobian",
        "measurement_function",
        "measurement_jacobian",
        "update_map",
    ],
}
requires = pytest.mark.requires
DATA = Path(__file__).resolve().parents[2] / "data" / "ekf_world.npz"


def _f(x):
    return np.asarray(x, dtype=float)


def _g(state, v, w, dt):
    """The seed's transitionModel, written out."""
    x, y, th = state
    return np.array([x + v * np.cos(th) * dt, y + v * np.sin(th) * dt, wrap_angle(th + w * dt)])


def _room(h=30, w=25):
    """A walled room with two blocks, unit cells (the seed's world convention)."""
    d = np.zeros((h, w))
    d[[0, -1], :] = 1.0
    d[:, [0, -1]] = 1.0
    d[8:12, 6:9] = 1.0
    d[18:21, 14:20] = 1.0
    return d


def _box(n=40):
    d = np.zeros((n, n))
    d[[0, -1], :] = 1.0
    d[:, [0, -1]] = 1.0
    return d


def _march(grid: OccupancyGrid, pose, angles, max_range, step=1e-3):
    """Brute force: walk every beam in tiny steps until it enters an obstacle or leaves the map."""
    t = np.arange(0.0, max_range + step / 2, step)
    phi = pose[2] + np.asarray(angles)[:, None]
    xy = np.stack([pose[0] + t * np.cos(phi), pose[1] + t * np.sin(phi)], -1)  # (B, T, 2)
    rc = grid.world_to_cell(xy)
    inside = grid.contains_cell(rc)
    occ = np.zeros(inside.shape, bool)
    occ[inside] = grid.occupied[rc[inside][:, 0], rc[inside][:, 1]]
    stop = occ | ~inside
    first = np.where(stop.any(1), stop.argmax(1), len(t) - 1)
    r = t[first]
    r[~inside[np.arange(len(r)), first] & stop.any(1)] = max_range  # left the map: max range
    return np.minimum(r, max_range)


def _ism_oracle(shape, state, scan, zmax=ZMAX, angles=None, beta=None):
    """Probabilistic Robotics Table 9.2 cell by cell (alpha = 1 cell, +1 / -0.2 / 0)."""
    scan = np.asarray(scan, dtype=float)
    angles = 2 * np.pi * np.arange(len(scan)) / len(scan) if angles is None else np.asarray(angles)
    beta = 2 * np.pi / len(scan) if beta is None else beta
    out = np.zeros(shape)
    x, y, th = state
    for row in range(shape[0]):
        for col in range(shape[1]):
            cx, cy = col + 0.5, row + 0.5
            r = np.hypot(cx - x, cy - y)
            phi = np.arctan2(cy - y, cx - x) - th
            diffs = np.abs(wrap_angle(phi - angles))
            k = int(np.argmin(diffs))
            zk = min(scan[k], zmax)
            if r > min(zmax, zk + 0.5) or diffs[k] > beta / 2:
                out[row, col] = 0.0
            elif zk < zmax and abs(r - zk) < 0.5:
                out[row, col] = 1.0
            elif r <= zk:
                out[row, col] = -0.2
    return out


def _load_world():
    with np.load(DATA) as npz:
        return {k: npz[k] for k in npz.files}


# ------------------------------------------------------------------------ transition_model (10)


@pytest.mark.grades("transition_model", points=5)
def test_transition_model_matches_the_seed(lab):
    """The unicycle step: position along the old heading, heading by rotation_speed * dt."""
    rng = np.random.default_rng(0)
    for _ in range(5):
        s = np.array([rng.uniform(0, 40), rng.uniform(0, 40), rng.uniform(-np.pi, np.pi)])
        v, w, dt = rng.uniform(0, 2), rng.uniform(-1, 1), rng.choice([0.1, 0.5])
        out = _f(lab.transition_model(s.copy(), v, w, dt))
        assert out.shape == (3,), "transition_model of one state (3,) must return shape (3,)"
        np.testing.assert_allclose(
            out,
            _g(s, v, w, dt),
            atol=1e-12,
            err_msg="x' = x + v cos(theta) dt, y' = y + v sin(theta) dt, theta' = theta + w dt",
        )
    # worked example: facing +y, turning: the position moves along the OLD heading
    np.testing.assert_allclose(
        _f(lab.transition_model([1.0, 2.0, np.pi / 2], 2.0, 1.0, 0.5)),
        [1.0, 3.0, np.pi / 2 + 0.5],
        atol=1e-12,
        err_msg="worked example: facing +y at speed 2, turn 1 rad/s, dt 0.5: (1, 2) -> (1, 3), "
        "heading pi/2 + 0.5",
    )


@pytest.mark.grades("transition_model", points=5)
def test_transition_model_wraps_heading(lab):
    """The heading is wrapped to [-pi, pi) and many steps of a turn close a circle."""
    out = _f(lab.transition_model([5.0, 5.0, 3.0], 0.0, 2.0, 0.5))
    np.testing.assert_allclose(
        out,
        [5.0, 5.0, 4.0 - 2 * np.pi],
        atol=1e-12,
        err_msg="heading 3 + 2 * 0.5 = 4 rad must wrap to 4 - 2 pi",
    )
    s = np.array([10.0, 10.0, 0.0])
    n = 400  # a full circle of turn rate 2 pi / 40 s in 0.1 s steps
    for _ in range(n):
        s = _f(lab.transition_model(s, 1.0, 2 * np.pi / 40.0, 0.1))
        assert -np.pi <= s[2] < np.pi, (
            "after every step of the turn the heading must be in [-pi, pi)"
        )
    # the Euler polygon of a full circle closes exactly
    # (the cosines and sines of 400 equally spaced headings sum to 0)
    np.testing.assert_allclose(
        s,
        [10.0, 10.0, 0.0],
        atol=1e-9,
        err_msg="400 Euler steps of a full circle (turn rate 2 pi / 40 s, dt 0.1) return to the "
        "start",
    )


# -------------------------------------------------------------------------- state_jacobian (10)


@pytest.mark.grades("state_jacobian", points=7)
def test_state_jacobian_against_finite_differences(lab):
    """G = dg/dx matches central differences of the seed's model at random states."""
    rng = np.random.default_rng(1)
    h = 1e-6
    for _ in range(8):
        s = np.array([rng.uniform(0, 40), rng.uniform(0, 40), rng.uniform(-3.0, 3.0)])
        v, w, dt = rng.uniform(0.1, 2), rng.uniform(-1, 1), 0.1
        G = _f(lab.state_jacobian(s.copy(), v, w, dt))
        assert G.shape == (3, 3), "state_jacobian must return a (3, 3) matrix"
        num = np.column_stack(
            [(_g(s + h * e, v, w, dt) - _g(s - h * e, v, w, dt)) / (2 * h) for e in np.eye(3)]
        )
        np.testing.assert_allclose(
            G,
            num,
            atol=1e-7,
            err_msg="G against central differences of the unicycle model at a random state",
        )


@pytest.mark.grades("state_jacobian", points=3)
def test_state_jacobian_worked_example(lab):
    """Facing +x at speed 2 for 0.5 s: only dy/dtheta = v dt = 1 is off the identity."""
    G = _f(lab.state_jacobian([3.0, 4.0, 0.0], 2.0, 0.7, 0.5))
    np.testing.assert_allclose(
        G,
        [[1, 0, 0], [0, 1, 1.0], [0, 0, 1]],
        atol=1e-12,
        err_msg="facing +x at speed 2 for 0.5 s: G = I with dy/dtheta = v dt = 1",
    )


# -------------------------------------------------------------------- measurement_function (15)


@pytest.mark.grades("measurement_function", points=9)
def test_measurement_function_against_brute_force_march(lab):
    """36 predicted ranges equal a 1 mm-step ray march (tolerance: the step) in two maps."""
    rng = np.random.default_rng(2)
    room = OccupancyGrid(_room(), 1.0)
    fine = OccupancyGrid(_room(), 0.5, origin=(-3.0, 2.0, 0.0))  # other resolution and origin
    for grid in (room, fine):
        free = np.argwhere(~grid.occupied)
        for idx in rng.choice(len(free), 3, replace=False):
            centre = grid.cell_to_world(free[idx])
            s = np.array(
                [
                    *(centre + rng.uniform(-0.4, 0.4, 2) * grid.resolution),
                    rng.uniform(-np.pi, np.pi),
                ]
            )
            got = _f(lab.measurement_function(s, grid))
            assert got.shape == (36,), "ray cast must return one range per beam: shape (36,)"
            np.testing.assert_allclose(
                got,
                _march(grid, s, ANGLES, ZMAX),
                atol=2e-3,
                err_msg="36 ranges against a 1 mm-step ray march from a random free pose",
            )


@pytest.mark.grades("measurement_function", points=2)
def test_measurement_function_evidence_map_threshold(lab):
    """An evidence array is an obstacle only where its score is above 0.5: 0.5 and 0.3 are not."""
    d = np.zeros((10, 30))
    d[:, 20] = 0.5  # exactly the threshold: not an obstacle
    d[:, 24] = 0.3  # positive evidence below the threshold: not an obstacle
    d[:, 28] = 0.51  # above: the first obstacle, face at x = 28
    z = _f(lab.measurement_function([12.5, 5.0, 0.0], d))
    assert z.shape == (36,), f"36 beams expected, got shape {z.shape}"
    assert z[0] == pytest.approx(15.5, abs=1e-9), (
        f"evidence map with scores 0.5 (x = 20), 0.3 (x = 24) and 0.51 (x = 28), robot at x = 12.5 "
        f"facing +x: beam 0 should end at the score-0.51 column, range 15.5; got {z[0]}"
    )


@pytest.mark.grades("measurement_function", points=4)
def test_measurement_function_worked_examples(lab):
    """Facing a wall: beam 0 = distance to its face; empty map: max range; n_beams (even 1)."""
    d = np.zeros((10, 30))
    d[:, 20] = 1.0  # a wall whose face is at x = 20
    grid = OccupancyGrid(d, 1.0)
    z = _f(lab.measurement_function([12.5, 5.0, 0.0], grid))
    assert z[0] == pytest.approx(7.5, abs=1e-9), (
        "wall face at x = 20, robot at (12.5, 5) facing +x: beam 0 range 7.5"
    )
    assert z[18] == pytest.approx(ZMAX, abs=1e-9), (
        "beam 18 points backwards and leaves the map: max range 20"
    )  # backwards: leaves the map -> max range
    z4 = _f(lab.measurement_function([12.5, 5.0, np.pi / 2], grid, n_beams=4, max_range=5.0))
    np.testing.assert_allclose(
        z4,
        [5.0, 5.0, 5.0, 5.0],
        atol=1e-9,
        err_msg="heading +y, 4 beams, max_range 5: +y, -x, -y leave the map, +x ends at 7.5 > 5",
    )  # +y, -x, -y leave the map; +x ends at 7.5 > 5
    z4 = _f(lab.measurement_function([12.5, 5.0, np.pi / 2], grid, n_beams=4, max_range=10.0))
    np.testing.assert_allclose(
        z4,
        [10.0, 10.0, 10.0, 7.5],
        atol=1e-9,
        err_msg="heading +y, 4 beams, max_range 10: beam 3 (+x) ends on the wall at 7.5",
    )  # beam 3 points along +x again
    one = _f(lab.measurement_function([12.5, 5.0, 0.0], grid, n_beams=1, max_range=10.0))
    assert one.shape == (1,), f"n_beams = 1: expected one range of shape (1,), got {one.shape}"
    np.testing.assert_allclose(
        one,
        [7.5],
        atol=1e-9,
        err_msg="one beam (n_beams = 1) facing the wall at 7.5: expected [7.5], shape (1,)",
    )
    empty = _f(lab.measurement_function([5.0, 5.0, 0.3], OccupancyGrid(np.zeros((10, 10)), 1.0)))
    np.testing.assert_allclose(
        empty, np.full(36, ZMAX), err_msg="a map without obstacles: every beam at max range"
    )


# -------------------------------------------------------------------- measurement_jacobian (10)


@pytest.mark.grades("measurement_jacobian", points=6)
def test_measurement_jacobian_against_finite_differences(lab):
    """H equals central differences of the exact ray cast with the same steps at random states."""
    rng = np.random.default_rng(3)
    grid = OccupancyGrid(_room(), 1.0)
    steps = np.array([0.05, 0.05, 0.005])
    for _ in range(5):
        s = np.array([rng.uniform(2, 23), rng.uniform(2, 7), rng.uniform(-np.pi, np.pi)])
        H = _f(lab.measurement_jacobian(s, grid, steps=tuple(steps)))
        assert H.shape == (36, 3), "measurement_jacobian must return (36, 3)"
        num = np.empty((36, 3))
        for j in range(3):
            e = np.eye(3)[j] * steps[j]
            num[:, j] = (
                cast_rays(grid, s + e, ANGLES, ZMAX)[0] - cast_rays(grid, s - e, ANGLES, ZMAX)[0]
            ) / (2 * steps[j])
        np.testing.assert_allclose(
            H,
            num,
            atol=1e-6,
            err_msg="H against central differences of the exact ray cast with the same steps",
        )


@pytest.mark.grades("measurement_jacobian", points=4)
def test_measurement_jacobian_analytic_wall(lab):
    """Facing walls squarely: dr0/dx = -1, dr9/dy = -1, other slopes 0; oblique dr/dtheta."""
    d = np.zeros((40, 40))
    d[:, 30] = 1.0
    d[25, :] = 1.0
    grid = OccupancyGrid(d, 1.0)
    H = _f(lab.measurement_jacobian([20.0, 15.0, 0.0], grid))
    np.testing.assert_allclose(
        H[0],
        [-1.0, 0.0, 0.0],
        atol=1e-6,
        err_msg="facing the x = 30 wall squarely from x = 20: dr0/dx = -1, no dy or dtheta slope",
    )
    np.testing.assert_allclose(
        H[9],
        [0.0, -1.0, 0.0],
        atol=1e-6,
        err_msg="beam 9 (+y) facing the y = 25 wall from y = 15: dr9/dy = -1",
    )
    # beam 4 (40 deg) hits the x = 30 face: r = 10 / cos(phi), dr/dtheta = 10 sin(phi) / cos(phi)^2
    phi = np.deg2rad(40.0)
    assert H[4, 2] == pytest.approx(10 * np.sin(phi) / np.cos(phi) ** 2, rel=2e-3), (
        "beam 4 (40 deg) on the face x = 30 from 10 units away: dr/dtheta = 10 sin(phi) / "
        "cos(phi)^2"
    )  # O(delta^2) of the difference


# -------------------------------------------------------------------- inverse_sensor_model (15)


@pytest.mark.grades("inverse_sensor_model", points=6)
def test_inverse_sensor_model_single_beam_classes(lab):
    """One beam along +x ending 5 cells ahead: free before, +1 at the end, 0 beyond and off it."""
    out = _f(
        lab.inverse_sensor_model(
            (20, 25), [3.5, 10.5, 0.0], [5.0], beam_angles=[0.0], beam_width=np.deg2rad(10.0)
        )
    )
    assert out.shape == (20, 25), "inverse_sensor_model must return the grid's shape (20, 25)"
    np.testing.assert_allclose(
        out[10, 3:8], -0.2, err_msg="cells the beam passes (x = 3.5 .. 7.5) are free"
    )
    assert out[10, 8] == 1.0, "the cell where the beam ends (centre at range 5) is occupied"
    np.testing.assert_allclose(out[10, 9:], 0.0, err_msg="cells beyond the hit are not reached")
    off = np.ones(out.shape, bool)
    off[10, 3:9] = False
    np.testing.assert_allclose(out[off], 0.0, err_msg="cells off the beam are not reached")
    # a max-range reading hits nothing: free up to zmax, never occupied
    out = _f(
        lab.inverse_sensor_model(
            (20, 40),
            [3.5, 10.5, 0.0],
            [8.0],
            max_range=8.0,
            beam_angles=[0.0],
            beam_width=np.deg2rad(10.0),
        )
    )
    np.testing.assert_allclose(
        out[10, 3:12],
        -0.2,
        err_msg="a max-range reading of 8: every cell up to 8 along the beam is free",
    )
    assert not np.any(out == 1.0), "a max-range reading hits nothing: no cell may be +1"


@pytest.mark.grades("inverse_sensor_model", points=6)
def test_inverse_sensor_model_matches_table_9_2(lab):
    """36-beam scans from random poses: every cell as a cell-by-cell Table 9.2 classifies it."""
    rng = np.random.default_rng(4)
    room = OccupancyGrid(_room(), 1.0)
    for _ in range(3):
        s = np.array([rng.uniform(3, 22), rng.uniform(2, 7), rng.uniform(-np.pi, np.pi)])
        scan = np.clip(cast_rays(room, s, ANGLES, ZMAX)[0] + rng.normal(0, 0.2, 36), 0, ZMAX)
        scan[rng.integers(0, 36, 3)] = ZMAX  # a few max-range readings
        got = _f(lab.inverse_sensor_model((30, 25), s, scan))
        expected = _ism_oracle((30, 25), s, scan)
        assert np.array_equal(got, expected), (
            f"{int(np.sum(got != expected))} cells classified differently"
        )


@pytest.mark.grades("inverse_sensor_model", points=3)
@requires(
    "test_inverse_sensor_model_single_beam_classes", "test_inverse_sensor_model_matches_table_9_2"
)
def test_inverse_sensor_model_bad_input(lab, refuses):
    """A NaN range, a negative range or a scan that does not match the beam angles: ValueError."""
    scan = np.full(36, 5.0)
    scan[3] = np.nan
    with refuses(ValueError, "scan with a NaN range (beam 3)"):
        lab.inverse_sensor_model((20, 20), [10.0, 10.0, 0.0], scan)
    with refuses(ValueError, "a scan of 35 ranges for 36 beam_angles"):
        lab.inverse_sensor_model((20, 20), [10.0, 10.0, 0.0], np.full(35, 5.0), beam_angles=ANGLES)
    negative = np.full(36, 5.0)
    negative[7] = -1.0
    with refuses(ValueError, "scan with a negative range (-1 at beam 7)"):
        lab.inverse_sensor_model((20, 20), [10.0, 10.0, 0.0], negative)


# ------------------------------------------------------------------------------ update_map (10)


@pytest.mark.grades("update_map", points=1)
def test_update_map_leaves_its_input_alone(lab):
    """update_map returns a new map: the map passed in keeps its values."""
    grid = np.random.default_rng(7).normal(0, 1, (30, 25))
    before = grid.copy()
    out = _f(lab.update_map(grid, [12.3, 5.2, 0.4], np.full(36, 4.0)))
    np.testing.assert_array_equal(grid, before, err_msg="update_map modified the map passed in")
    np.testing.assert_allclose(
        out,
        before + _ism_oracle((30, 25), np.array([12.3, 5.2, 0.4]), np.full(36, 4.0)),
        atol=1e-12,
        err_msg="a 36-beam scan of 4-unit ranges from (12.3, 5.2, 0.4) on a random map: "
        "expected the map plus the inverse sensor model",
    )


@pytest.mark.grades("update_map", points=4)
def test_update_map_accumulates(lab):
    """From zeros: one scan gives the inverse sensor model, the same scan twice gives twice it."""
    rng = np.random.default_rng(5)
    room = OccupancyGrid(_room(), 1.0)
    s = np.array([12.3, 5.2, 0.4])
    scan = np.clip(cast_rays(room, s, ANGLES, ZMAX)[0] + rng.normal(0, 0.2, 36), 0, ZMAX)
    zero = np.zeros((30, 25))
    once = _f(lab.update_map(zero.copy(), s, scan))
    expected = _ism_oracle((30, 25), s, scan)
    np.testing.assert_allclose(
        once,
        expected,
        atol=1e-12,
        err_msg="from zeros, one scan: the map is the inverse sensor model (Table 9.2)",
    )
    twice = _f(lab.update_map(once, s, scan))
    np.testing.assert_allclose(
        twice, 2 * expected, atol=1e-12, err_msg="the same scan twice: twice the evidence"
    )
    # from any prior map, the update adds
    prior = rng.normal(0, 1, (30, 25))
    np.testing.assert_allclose(
        _f(lab.update_map(prior.copy(), s, scan)),
        prior + expected,
        atol=1e-12,
        err_msg="from a random prior map the update adds the evidence",
    )


@pytest.mark.grades("update_map", points=3)
def test_update_map_leaves_unseen_cells(lab):
    """Short ranges: cells no beam reaches stay exactly 0; the hit ring is +1, inside it -0.2."""
    s = np.array([20.5, 20.5, 0.0])
    scan = np.full(36, 3.0)
    out = _f(lab.update_map(np.zeros((40, 40)), s, scan))
    cx, cy = np.meshgrid(np.arange(40) + 0.5, np.arange(40) + 0.5)
    far = np.hypot(cx - s[0], cy - s[1]) > 3.5
    assert np.all(out[far] == 0.0), (
        "scan of 3-unit ranges: cells farther than 3.5 from the robot must stay exactly 0"
    )
    ring = ~far & (np.hypot(cx - s[0], cy - s[1]) > 2.5)
    assert np.all(out[ring] == 1.0), (
        "cells between 2.5 and 3.5 from the robot (the hit ring) must be +1"
    )
    assert np.all(out[np.hypot(cx - s[0], cy - s[1]) <= 2.5] == -0.2), (
        "cells within 2.5 of the robot (the beams pass them) must be -0.2"
    )


@pytest.mark.grades("update_map", points=2)
@requires("test_update_map_accumulates")
def test_update_map_bad_input(lab, refuses):
    """NaN ranges raise ValueError."""
    with refuses(ValueError, "scan of NaN ranges"):
        lab.update_map(np.zeros((20, 20)), [10.0, 10.0, 0.0], np.full(36, np.nan))


# ------------------------------------------------------------------------ ekf_mapping_step (30)

# The hand-written EKF scenario: a 40 x 40 walled box whose walls are already in
# the map (score 3) and whose inside is known free (score -1). One scan adds at
# most +1 to an inside cell, so the occupancy the filter ray-casts in stays the
# box, and every one of the 36 beams ends on a straight face away from corners
# and from zmax: ranges are linear in x, y and smooth in theta there.
_P0 = np.diag([0.09, 0.09, 0.01])
_Q = np.diag([0.0001, 0.0001, 0.08])
_X0 = np.array([20.0, 20.0, 0.05])
_TRUE = np.array([20.4, 19.7, 0.13])
_CMD = (1.0, 0.3, 0.1)  # speed, rotation_speed, dt


def _box_scenario():
    box = OccupancyGrid(_box(), 1.0)
    prior = np.where(_box() > 0, 3.0, -1.0)
    rng = np.random.default_rng(6)
    scan = cast_rays(box, _TRUE, ANGLES, ZMAX)[0] + rng.normal(0, 0.2, 36)
    return box, prior, np.clip(scan, 0, ZMAX)


def _ekf_by_hand(box, x0, p0, q, r, scan, cmd=_CMD):
    v, w, dt = cmd
    xp = _g(x0, v, w, dt)
    G = np.eye(3)
    G[0, 2], G[1, 2] = -v * np.sin(x0[2]) * dt, v * np.cos(x0[2]) * dt
    pp = G @ p0 @ G.T + q
    hx = cast_rays(box, xp, ANGLES, ZMAX)[0]
    d = np.array([1e-3, 1e-3, 1e-5])  # near-exact slopes: ranges are linear/smooth here
    H = np.column_stack(
        [
            (cast_rays(box, xp + e, ANGLES, ZMAX)[0] - cast_rays(box, xp - e, ANGLES, ZMAX)[0])
            / (2 * e[j])
            for j, e in enumerate(np.diag(d))
        ]
    )
    S = H @ pp @ H.T + r
    K = pp @ H.T @ np.linalg.inv(S)
    x = xp + K @ (scan - hx)
    x[2] = wrap_angle(x[2])
    ikh = np.eye(3) - K @ H
    return x, ikh @ pp @ ikh.T + K @ r @ K.T, xp, xp + K @ (scan - hx)


@pytest.mark.grades("ekf_mapping_step", points=8)
def test_ekf_step_equals_hand_written_ekf(lab):
    """State and covariance equal Table 3.3 computed by hand (numpy) on the same numbers.

    Tolerance: the student's central-difference steps for H are free; here
    any steps up to 0.1 cell and 0.02 rad move the state by < 2e-5 and the
    covariance by < 3e-6 (measured against near-exact slopes), while the
    correction itself moves the state by 0.2 to 0.4.
    """
    box, prior, scan = _box_scenario()
    for r in (np.eye(36), 0.04 * np.eye(36)):
        state, cov, new_map = lab.ekf_mapping_step(
            (_X0.copy(), _P0.copy(), _Q.copy(), r.copy()),
            prior.copy(),
            *_CMD[:2],
            scan.copy(),
            _CMD[2],
        )
        x, p, _, _ = _ekf_by_hand(box, _X0, _P0, _Q, r, scan)
        state, cov = _f(state), _f(cov)
        assert state.shape == (3,) and cov.shape == (3, 3) and _f(new_map).shape == (40, 40), (
            "shapes: state (3,), covariance (3, 3), map (40, 40)"
        )
        np.testing.assert_allclose(
            state, x, atol=2e-4, err_msg="state after predict + correct against Table 3.3 by hand"
        )
        np.testing.assert_allclose(
            cov,
            p,
            atol=2e-5,
            rtol=1e-2,
            err_msg="covariance after predict + correct (Joseph form) against Table 3.3 by hand",
        )
        assert np.linalg.norm(state[:2] - _TRUE[:2]) < np.linalg.norm(
            _g(_X0, *_CMD)[:2] - _TRUE[:2]
        ), "the correction should move the estimate towards the true pose"


@pytest.mark.grades("ekf_mapping_step", points=4)
def test_ekf_step_maps_from_the_predicted_pose(lab):
    """The returned map is the old map plus the inverse sensor model at the PREDICTED pose."""
    box, prior, scan = _box_scenario()
    _, _, new_map = lab.ekf_mapping_step(
        (_X0.copy(), _P0.copy(), _Q.copy(), np.eye(36)),
        prior.copy(),
        *_CMD[:2],
        scan.copy(),
        _CMD[2],
    )
    xp = _g(_X0, *_CMD)
    np.testing.assert_allclose(
        _f(new_map),
        prior + _ism_oracle((40, 40), xp, scan),
        atol=1e-12,
        err_msg="new map = old map + inverse sensor model at the predicted pose g(u, mu)",
    )


@pytest.mark.grades("ekf_mapping_step", points=6)
@requires("test_ekf_step_equals_hand_written_ekf", "test_ekf_step_maps_from_the_predicted_pose")
def test_ekf_mapping_on_the_bundled_run(lab):
    """The first 25 s of the bundled 40 x 40 run: pose error and map agreement with the true world.

    Bounds: the map has one cell per unit and is built from the filter's own
    estimate (its errors are not in the state), so even a correct filter
    drifts by about a cell: the reference ends 0.9 units off (worst 1.7);
    other correct Jacobian steps (0.02 to 0.3 cell) end 1.2 to 2.3 off (worst
    2.4). A filter with a broken correction ends tens of units off. Map:
    cells seen and scored > 0.5 against the true obstacles (reference 85 %
    agreement, 86 % of the seen obstacle cells found).
    """
    d = _load_world()
    n = 250
    x, p = d["initial_state"].copy(), d["initial_cov"].copy()
    q, r = d["process_noise"], np.eye(36)
    m = np.zeros(d["world"].shape)
    err = np.empty(n)
    for k in range(n):
        x, p, m = lab.ekf_mapping_step(
            (x, p, q, r),
            m,
            float(d["speed"][k]),
            float(d["rotation_speed"][k]),
            d["scans"][k],
            float(d["dt"]),
        )
        x, p, m = _f(x), _f(p), _f(m)
        err[k] = np.hypot(*(x[:2] - d["states"][k + 1, :2]))
    assert err[-1] < 2.5, f"final position error {err[-1]:.2f} units (bound 2.5)"
    assert err.max() < 3.0, f"worst position error {err.max():.2f} units (bound 3)"
    assert abs(wrap_angle(x[2] - d["states"][n, 2])) < 0.15, (
        "final heading within 0.15 rad of the truth on the bundled run"
    )
    world = d["world"] > 0.5
    seen = m != 0
    assert seen.sum() > 0.6 * world.size, "most of the world is seen within 20 units"
    agree = np.mean((m > 0.5)[seen] == world[seen])
    assert agree > 0.75, f"only {agree:.0%} of the seen cells agree with the true world"
    assert np.mean((m > 0.5)[world & seen]) > 0.6, "most seen obstacle cells should score > 0.5"


@pytest.mark.grades("ekf_mapping_step", points=2)
@requires("test_ekf_step_equals_hand_written_ekf")
def test_ekf_step_bad_input(lab, refuses):
    """A scan of the wrong length or with NaN ranges raises ValueError."""
    args = ((_X0, _P0, _Q, np.eye(36)), np.zeros((40, 40)), 1.0, 0.1)
    with refuses(ValueError, "a scan of 35 ranges (the robot has 36 beams)"):
        lab.ekf_mapping_step(*args, np.full(35, 5.0), 0.1)
    bad = np.full(36, 5.0)
    bad[0] = np.nan
    with refuses(ValueError, "scan with a NaN range (beam 0)"):
        lab.ekf_mapping_step(*args, bad, 0.1)


@pytest.mark.grades("ekf_mapping_step", points=3)
def test_ekf_step_prediction_linearizes_at_the_previous_mean(lab):
    """With an uninformative sensor (R = 1e8 I) the step is the prediction: G P G^T + Q, G at
    mu_{t-1}.

    A fast turn (omega dt = 1.5 rad) makes G at the previous heading and at the
    predicted one very different.
    """
    box, prior, scan = _box_scenario()
    x0, p0 = np.array([20.0, 20.0, 0.3]), np.diag([0.09, 0.09, 0.04])
    v, w, dt = 2.0, 3.0, 0.5
    state, cov, _ = lab.ekf_mapping_step(
        (x0.copy(), p0.copy(), _Q.copy(), 1e8 * np.eye(36)), prior.copy(), v, w, scan.copy(), dt
    )
    G = np.eye(3)
    G[0, 2], G[1, 2] = -v * np.sin(x0[2]) * dt, v * np.cos(x0[2]) * dt
    np.testing.assert_allclose(
        _f(state),
        _g(x0, v, w, dt),
        atol=1e-5,
        err_msg="R = 1e8 I: the state is the predicted mean g(u, mu) (speed 2, turn 3 rad/s, dt "
        "0.5)",
    )
    np.testing.assert_allclose(
        _f(cov),
        G @ p0 @ G.T + _Q,
        atol=1e-5,
        err_msg="R = 1e8 I: the covariance is G P G^T + Q with G at the previous mean (heading "
        "0.3)",
    )


@pytest.mark.grades("ekf_mapping_step", points=3)
@requires("test_ekf_step_equals_hand_written_ekf")
def test_ekf_step_wraps_a_corrected_heading_near_pi(lab):
    """A correction that turns the heading across +-pi: wrapped, and the same as away from pi.

    Predicted heading pi - 0.02, true heading pi + 0.15: the correction crosses pi.
    The box world is symmetric under a half turn about its centre, so the same step
    turned by pi (heading -0.02 towards 0.15, no wrap needed) must give the same
    estimate turned back, whatever the formulas: only a missing wrap fails here.
    """
    box = OccupancyGrid(_box(), 1.0)
    prior = np.where(_box() > 0, 3.0, -1.0)
    true = np.array([19.9, 20.0, np.pi + 0.15 - 2 * np.pi])
    scan = np.clip(
        cast_rays(box, true, ANGLES, ZMAX)[0] + np.random.default_rng(8).normal(0, 0.2, 36), 0, ZMAX
    )
    cmd = (1.0, 0.1, 0.1)
    x0 = np.array([20.013, 19.987, np.pi - 0.03])
    turned = np.array([40.0 - x0[0], 40.0 - x0[1], x0[2] - np.pi])
    _, _, _, unwrapped = _ekf_by_hand(box, x0, _P0, _Q, np.eye(36), scan, cmd)
    assert unwrapped[2] > np.pi, (
        f"test self-check: the correction must cross pi, got {unwrapped[2]}"
    )
    state, cov, ref, ref_cov = (
        _f(v)
        for x in (x0, turned)
        for v in lab.ekf_mapping_step(
            (x.copy(), _P0.copy(), _Q.copy(), np.eye(36)),
            prior.copy(),
            cmd[0],
            cmd[1],
            scan,
            cmd[2],
        )[:2]
    )
    assert -np.pi <= state[2] < np.pi, (
        f"corrected heading {state[2]:.4f} rad (true {true[2]:.4f}): must be wrapped to [-pi, pi)"
    )
    mirrored = [40.0 - ref[0], 40.0 - ref[1], 0.0]
    np.testing.assert_allclose(
        [state[0], state[1], wrap_angle(state[2] - ref[2] - np.pi)],
        mirrored,
        atol=1e-6,
        err_msg="state after crossing pi against the same step turned by pi about the box's centre "
        "(x, y mirrored, heading + pi)",
    )
    flip = np.diag([-1.0, -1.0, 1.0])
    np.testing.assert_allclose(
        cov,
        flip @ ref_cov @ flip,
        atol=1e-9,
        err_msg="covariance after crossing pi against the same step turned by pi",
    )


@pytest.mark.grades("ekf_mapping_step", points=2)
def test_ekf_step_from_an_empty_map_corrects_in_the_new_map(lab):
    """First step, empty map: the correction ray-casts in the map that already holds this scan.

    In the empty map every predicted range is zmax and H = 0, so nothing would be
    corrected; in the updated map the 36 ranges pin the position down.
    """
    _, _, scan = _box_scenario()
    state, cov, new_map = lab.ekf_mapping_step(
        (_X0.copy(), _P0.copy(), _Q.copy(), np.eye(36)),
        np.zeros((40, 40)),
        *_CMD[:2],
        scan,
        _CMD[2],
    )
    v, _, dt = _CMD
    G = np.eye(3)
    G[0, 2], G[1, 2] = -v * np.sin(_X0[2]) * dt, v * np.cos(_X0[2]) * dt
    predicted = G @ _P0 @ G.T + _Q
    np.testing.assert_allclose(
        _f(new_map),
        _ism_oracle((40, 40), _g(_X0, *_CMD), scan),
        atol=1e-12,
        err_msg="from an empty map: expected the returned map to be this scan's inverse sensor "
        "model at the predicted pose",
    )
    assert np.all(np.linalg.eigvalsh(_f(cov)) > 0), (
        f"the covariance after the step must stay positive definite, got eigenvalues "
        f"{np.linalg.eigvalsh(_f(cov))}"
    )
    got = np.trace(_f(cov)[:2, :2])
    assert got < 0.5 * np.trace(predicted[:2, :2]), (
        f"from an empty map the position variance must shrink in the correction: predicted "
        f"trace {np.trace(predicted[:2, :2]):.4f}, got {got:.4f} (was the map of this scan used?)"
    )


@pytest.mark.grades("ekf_mapping_step", points=2)
def test_ekf_step_no_return_reads_as_max_range(lab):
    """A reading of inf (no return) gives the same step as a reading of exactly max_range."""
    box, prior, scan = _box_scenario()
    capped, endless = scan.copy(), scan.copy()
    capped[[3, 20, 31]] = ZMAX
    endless[[3, 20]] = np.inf
    endless[31] = 2 * ZMAX
    results = [
        lab.ekf_mapping_step(
            (_X0.copy(), _P0.copy(), _Q.copy(), np.eye(36)), prior.copy(), *_CMD[:2], z, _CMD[2]
        )
        for z in (capped, endless)
    ]
    x, p, _, _ = _ekf_by_hand(box, _X0, _P0, _Q, np.eye(36), capped)
    np.testing.assert_allclose(
        _f(results[0][0]),
        x,
        atol=2e-4,
        err_msg="readings of exactly max_range: expected the state of Table 3.3 by hand",
    )
    for name, a, b in zip(("state", "covariance", "map"), *results, strict=True):
        np.testing.assert_allclose(
            _f(b),
            _f(a),
            atol=1e-9,
            err_msg=f"{name}: readings inf, inf, 40 must count as max_range = 20",
        )
