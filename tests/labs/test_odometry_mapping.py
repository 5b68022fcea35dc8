"""Hidden tests for lab 04, mapping with raw odometry (seed 004, part 2). 100 points.

Every test calls only ``lab.<exercise>(...)`` with plain data (arrays, floats,
dicts, OccupancyGrid) and compares results after ``np.asarray(..., dtype=float)``,
so it works on the reference solution and, with ``--notebook``, across the
grader's process boundary. Nothing here is random without a fixed seed.

Oracles: an exact brute-force supercover (per cell, the parameter interval on
which the segment lies in the half-open square), dense sampling of the
segment, hand-computed scans, a literal cell-by-cell transcription of
Probabilistic Robotics Table 9.2, and the bundled ``data/mapping.bag`` against
the true floor plan ``data/office.yaml``.

Points: scan_endpoints 15, beam_cells 25, counting_map_update 25,
occupancy_from_counts 5, clip_map 5, logodds_update 20, logodds_to_probability 5.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from robolab import DATA_DIR
from robolab.geometry import compose, wrap_angle
from robolab.maps import OccupancyGrid, load_map

RNG_SEED = 404
#: CPU seconds the reference solution's worker uses while graded (loading and every call,
#: children included: `cpu_seconds` of the correct example in `make grade`'s gradebook.json,
#: 2026-12-02): a submission gets 8 times that in total, at least 20 s (docs/grading.md).
REFERENCE_CPU_SECONDS = 3.2

#: Exercises each exercise is likely to call (the feedback names them when they fail).
USES = {"counting_map_update": ["beam_cells"]}
requires = pytest.mark.requires


def _f(x):
    return np.asarray(x, dtype=float)


def _scan(ranges, angles, range_min=0.05, range_max=8.0):
    return {
        "ranges": np.asarray(ranges, dtype=float),
        "angles": np.asarray(angles, dtype=float),
        "range_min": float(range_min),
        "range_max": float(range_max),
    }


def _grid(rows, cols, resolution, origin=(0.0, 0.0, 0.0)):
    return OccupancyGrid(np.full((rows, cols), -1.0), resolution, np.asarray(origin, dtype=float))


def _cells_by_beam(result, n_beams):
    cells, beam = result
    cells = np.asarray(cells, dtype=float)
    beam = np.asarray(beam, dtype=float)
    assert cells.ndim == 2 and cells.shape[1] == 2, f"cells must be (N, 2), got {cells.shape}"
    assert beam.shape == (cells.shape[0],), f"beam must be (N,) like cells, got {beam.shape}"
    assert np.all(cells == np.round(cells)), "cell indices must be integers"
    assert np.all(beam == np.round(beam)) and np.all((beam >= 0) & (beam < n_beams)), (
        "bad beam indices"
    )
    out = []
    for b in range(n_beams):
        out.append([tuple(int(v) for v in c) for c in cells[beam == b]])
    return out


def _supercover(s, e):
    """Exact set of cells (i, j) with floor(p(t)) = (i, j) for some t in [0, 1].

    For each candidate cell the parameter interval on which i <= p_r(t) < i + 1
    and j <= p_c(t) < j + 1 is intersected with [0, 1], keeping track of which
    ends are open (the half-open squares of OccupancyGrid.world_to_cell).
    """
    s, e = np.asarray(s, dtype=float), np.asarray(e, dtype=float)
    d = e - s
    lo_c = np.floor(np.minimum(s, e)).astype(int)
    hi_c = np.floor(np.maximum(s, e)).astype(int)
    out = set()
    for i in range(lo_c[0], hi_c[0] + 1):
        for j in range(lo_c[1], hi_c[1] + 1):
            lo, lo_closed, hi, hi_closed = 0.0, True, 1.0, True
            inside = True
            for axis, c in ((0, i), (1, j)):
                if d[axis] == 0:
                    inside &= c <= s[axis] < c + 1
                    continue
                ta, tb = (c - s[axis]) / d[axis], (c + 1 - s[axis]) / d[axis]
                if d[axis] > 0:
                    a_lo, a_loc, a_hi, a_hic = ta, True, tb, False
                else:
                    a_lo, a_loc, a_hi, a_hic = tb, False, ta, True
                if a_lo > lo or (a_lo == lo and not a_loc):
                    lo, lo_closed = a_lo, a_loc
                if a_hi < hi or (a_hi == hi and not a_hic):
                    hi, hi_closed = a_hi, a_hic
            if inside and (lo < hi or (lo == hi and lo_closed and hi_closed)):
                out.add((i, j))
    return out


# ------------------------------------------------------------------ scan_endpoints (15)


@pytest.mark.grades("scan_endpoints", points=4)
def test_scan_endpoints_hand_computed(lab):
    """Endpoints of a laser at the robot's centre, by hand."""
    scan = _scan([1.0, 2.0, 0.5], [0.0, np.pi / 2, -np.pi / 4])
    got = _f(lab.scan_endpoints(scan, np.array([1.0, 2.0, 0.0]), np.zeros(3)))
    h = 0.5 / np.sqrt(2)
    np.testing.assert_allclose(
        got,
        [[2.0, 2.0], [1.0, 4.0], [1.0 + h, 2.0 - h]],
        atol=1e-9,
        err_msg="laser at the robot's centre (1, 2, 0): ranges [1, 2, 0.5] at angles [0, pi/2, "
        "-pi/4]",
    )
    # the robot turned by 90 degrees: every beam turns with it
    got = _f(lab.scan_endpoints(scan, np.array([0.0, 0.0, np.pi / 2]), np.zeros(3)))
    np.testing.assert_allclose(
        got,
        [[0.0, 1.0], [-2.0, 0.0], [h, h]],
        atol=1e-9,
        err_msg="robot at (0, 0) facing +y (pi/2): every beam turns with it",
    )


@pytest.mark.grades("scan_endpoints", points=4)
def test_scan_endpoints_rotated_and_offset_laser(lab):
    """A laser mounted backwards (yaw = pi) 0.1 m ahead of a robot facing +y."""
    scan = _scan([2.0, 1.0, 3.0], [0.0, np.pi / 2, np.pi])
    got = _f(lab.scan_endpoints(scan, np.array([1.0, 2.0, np.pi / 2]), np.array([0.1, 0.0, np.pi])))
    # laser at (1, 2.1) looking towards -y: beam 0 -> -y, beam pi/2 -> +x, beam pi -> +y
    np.testing.assert_allclose(
        got,
        [[1.0, 0.1], [2.0, 2.1], [1.0, 5.1]],
        atol=1e-9,
        err_msg="laser yawed by pi, 0.1 m ahead of a robot at (1, 2) facing +y",
    )
    # a laser offset sideways and yawed by -pi/2 on a robot at theta = pi
    got = _f(
        lab.scan_endpoints(
            _scan([1.5], [0.0]), np.array([0.0, 0.0, np.pi]), np.array([0.2, 0.3, -np.pi / 2])
        )
    )
    # laser at (-0.2, -0.3) heading pi/2 -> endpoint (-0.2, 1.2)
    np.testing.assert_allclose(
        got,
        [[-0.2, 1.2]],
        atol=1e-9,
        err_msg="laser at (0.2, 0.3, -pi/2) on a robot at (0, 0, pi): one beam of 1.5 m",
    )


@pytest.mark.grades("scan_endpoints", points=3)
def test_scan_endpoints_drop_invalid_ranges(lab):
    """0, inf, NaN, below range_min, at or above range_max and negative ranges give no endpoint."""
    ranges = [0.0, np.inf, np.nan, 0.01, 9.0, 8.0, -1.0, 3.0, -np.inf, 0.05]
    angles = np.linspace(0.0, 0.9, len(ranges))
    got = _f(lab.scan_endpoints(_scan(ranges, angles), np.zeros(3), np.zeros(3)))
    expected = [
        [3.0 * np.cos(angles[7]), 3.0 * np.sin(angles[7])],
        [0.05 * np.cos(angles[9]), 0.05 * np.sin(angles[9])],
    ]
    assert got.shape == (2, 2), (
        f"only the ranges 3.0 and 0.05 (= range_min) are hits; got {got.shape[0]} endpoints"
    )
    np.testing.assert_allclose(
        got,
        expected,
        atol=1e-9,
        err_msg="endpoints of the hits 3.0 and 0.05 (= range_min) among 0, inf, NaN, 0.01, 9, 8, "
        "-1, -inf",
    )
    none = _f(lab.scan_endpoints(_scan([np.nan, np.inf], [0.0, 1.0]), np.zeros(3), np.zeros(3)))
    assert none.size == 0, "ranges [NaN, inf]: no hit, so no endpoint; expected an empty result"


@pytest.mark.grades("scan_endpoints", points=2)
def test_scan_endpoints_zero_reading_with_range_min_zero(lab):
    """With range_min = 0 a zero reading is still no hit (a hit needs r > 0).

    A reading of range_max is none either.
    """
    scan = _scan(
        [0.0, 1.5, 0.0, 4.0, 2.0], [0.0, 0.5, 1.0, 1.5, -2.0], range_min=0.0, range_max=4.0
    )
    got = _f(lab.scan_endpoints(scan, np.array([1.0, -1.0, 0.3]), np.zeros(3)))
    expected = [
        [1.0 + 1.5 * np.cos(0.8), -1.0 + 1.5 * np.sin(0.8)],
        [1.0 + 2.0 * np.cos(-1.7), -1.0 + 2.0 * np.sin(-1.7)],
    ]
    assert got.shape == (2, 2), (
        f"ranges [0, 1.5, 0, 4, 2] with range_min = 0, range_max = 4: only 1.5 and 2 are hits, "
        f"expected 2 endpoints, got {got.shape[0]}"
    )
    np.testing.assert_allclose(
        got,
        expected,
        atol=1e-9,
        err_msg="endpoints of the two hits (robot at (1, -1), heading 0.3)",
    )


@pytest.mark.grades("scan_endpoints", points=2)
@requires("test_scan_endpoints_hand_computed", "test_scan_endpoints_rotated_and_offset_laser")
def test_scan_endpoints_bad_input(lab, refuses):
    """Wrong pose shapes and mismatched ranges / angles raise ValueError."""
    scan = _scan([1.0, 2.0], [0.0, 1.0])
    with refuses(ValueError, "pose of 2 numbers, not (x, y, theta)"):
        lab.scan_endpoints(scan, np.zeros(2), np.zeros(3))
    with refuses(ValueError, "laser_offset of 4 numbers, not (x, y, theta)"):
        lab.scan_endpoints(scan, np.zeros(3), np.zeros(4))
    with refuses(ValueError, "a scan of 3 ranges for 2 angles"):
        lab.scan_endpoints(_scan([1.0, 2.0, 3.0], [0.0, 1.0]), np.zeros(3), np.zeros(3))


# ------------------------------------------------------------------ beam_cells (25)


@pytest.mark.grades("beam_cells", points=12)
def test_beam_cells_match_brute_force_supercover(lab):
    """Random segments: exactly the cells the segment touches (exact oracle and dense sampling)."""
    rng = np.random.default_rng(RNG_SEED)
    n = 150
    start = rng.uniform(-6.0, 6.0, (n, 2))
    end = start + rng.uniform(-9.0, 9.0, (n, 2)) * rng.uniform(0.05, 1.0, (n, 1))
    end[:10, 0] = start[:10, 0] + 0.0  # horizontal beams (constant row coordinate)
    end[10:20, 1] = start[10:20, 1] + 0.0  # vertical beams
    end[20:23] = start[20:23]  # zero length
    per_beam = _cells_by_beam(lab.beam_cells(start, end), n)
    t = np.linspace(0.0, 1.0, 4001)
    for b in range(n):
        got = set(per_beam[b])
        expected = _supercover(start[b], end[b])
        sampled = {
            tuple(c) for c in np.floor(start[b] + t[:, None] * (end[b] - start[b])).astype(int)
        }
        assert sampled <= got, (
            f"beam {start[b]} -> {end[b]}: misses touched cells {sorted(sampled - got)[:5]}"
        )
        assert got == expected, (
            f"beam {start[b]} -> {end[b]}: missing {sorted(expected - got)[:5]}, "
            f"extra {sorted(got - expected)[:5]}"
        )


@pytest.mark.grades("beam_cells", points=5)
def test_beam_cells_hand_computed(lab):
    """Axis-aligned beams on cell boundaries, a reversed beam, a one-cell beam."""
    starts = np.array([[0.5, 2.0], [1.0, 0.5], [0.2, 0.3], [3.5, 0.5], [0.0, 0.0]])
    ends = np.array([[0.5, 5.0], [1.0, -2.0], [0.7, 0.9], [0.5, 1.2], [2.0, 1.0]])
    per_beam = _cells_by_beam(lab.beam_cells(starts, ends), len(starts))
    expected = [
        {(0, 2), (0, 3), (0, 4), (0, 5)},  # along row 0, ends exactly on col 5's left edge
        {(1, 0), (1, -1), (1, -2)},  # along the line row = 1 (which belongs to row 1), leftwards
        {(0, 0)},  # inside one cell
        # p = (3.5 - 3t, 0.5 + 0.7t) enters col 1 at t = 5/7, row 1.357
        {(3, 0), (2, 0), (1, 0), (1, 1), (0, 1)},
        # crosses row 1 at col 0.5, ends on the corner (2, 1): floor(end) is the end cell
        {(0, 0), (1, 0), (2, 1)},
    ]
    for b, exp in enumerate(expected):
        assert set(per_beam[b]) == exp, (
            f"beam {starts[b]} -> {ends[b]}: expected {sorted(exp)}, got {sorted(per_beam[b])}"
        )


@pytest.mark.grades("beam_cells", points=5)
def test_beam_cells_shared_start_order_and_no_duplicates(lab):
    """One start for many beams; each beam runs from floor(start) to floor(end), no cell twice."""
    start = np.array([10.3, 20.6])
    ang = np.linspace(-np.pi, np.pi, 72, endpoint=False)
    ends = (
        start + np.stack([np.sin(ang), np.cos(ang)], -1) * np.linspace(0.2, 30.0, ang.size)[:, None]
    )
    per_beam = _cells_by_beam(lab.beam_cells(start, ends), ang.size)
    for b, cells in enumerate(per_beam):
        assert len(cells) == len(set(cells)), f"beam {b} lists a cell twice"
        assert cells[0] == (10, 20), (
            f"beam {b} must start in the start cell (10, 20), got {cells[0]}"
        )
        assert cells[-1] == tuple(np.floor(ends[b]).astype(int)), (
            f"beam {b} must end in its end cell"
        )
        steps = (
            np.abs(np.diff(np.array(cells), axis=0)).max(axis=1) if len(cells) > 1 else np.ones(0)
        )
        assert np.all(steps == 1), (
            f"beam {b}: consecutive cells must be neighbours (ordered along the beam)"
        )
        assert set(cells) == _supercover(start, ends[b]), (
            "beam from (10.3, 20.6): cells must be exactly the supercover of the segment"
        )


@pytest.mark.grades("beam_cells", points=3)
@requires("test_beam_cells_match_brute_force_supercover", "test_beam_cells_hand_computed")
def test_beam_cells_bad_input(lab, refuses):
    """Wrong shapes, mismatched beam counts and NaN raise ValueError."""
    with refuses(ValueError, "start_cell of 3 numbers, not (col, row)"):
        lab.beam_cells(np.zeros(3), np.ones((2, 2)))
    with refuses(ValueError, "start_cell of shape (3, 2) for 2 end cells"):
        lab.beam_cells(np.zeros((3, 2)), np.ones((2, 2)))
    with refuses(ValueError, "end_cell (1, NaN)"):
        lab.beam_cells(np.zeros(2), np.array([[1.0, np.nan]]))


# ------------------------------------------------------------------ counting_map_update (25)


@pytest.mark.grades("counting_map_update", points=5)
def test_counting_update_hand_computed(lab):
    """A hit, a no-return beam and a NaN on a 1 m grid, counted by hand."""
    grid = _grid(6, 6, 1.0)
    scan = _scan(
        [3.2, np.inf, np.nan, 0.01],
        [0.0, np.pi / 2, np.pi / 4, -np.pi / 2],
        range_min=0.05,
        range_max=4.0,
    )
    hits, visits = lab.counting_map_update(
        np.zeros((6, 6)), np.zeros((6, 6)), scan, np.array([0.5, 0.5, 0.0]), grid
    )
    hits, visits = _f(hits), _f(visits)
    exp_hits = np.zeros((6, 6))
    exp_hits[0, 3] = 1  # the endpoint (3.7, 0.5)
    exp_visits = np.zeros((6, 6))
    exp_visits[0, 0:4] += 1  # the hit beam, end cell included
    exp_visits[0:5, 0] += 1  # the no-return beam: free up to range_max (y = 4.5, row 4)
    np.testing.assert_array_equal(
        hits,
        exp_hits,
        err_msg="hits: one hit, at the cell (0, 3) of the endpoint (3.7, 0.5); NaN and 0.01 "
        "ignored",
    )
    np.testing.assert_array_equal(
        visits,
        exp_visits,
        err_msg="visits: (0, 0)..(0, 3) from the hit beam, (0, 0)..(4, 0) from the inf beam up "
        "to range_max",
    )


@pytest.mark.grades("counting_map_update", points=5)
def test_counting_update_matches_supercover_counts(lab):
    """Random scans on an offset grid: visits and hits per cell equal the brute-force counts."""
    rng = np.random.default_rng(RNG_SEED + 1)
    grid = _grid(30, 40, 0.25, origin=(-2.3, 1.7, 0.0))
    angles = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    h0 = rng.integers(0, 3, grid.shape).astype(float)
    v0 = h0 + rng.integers(0, 3, grid.shape)
    for trial in range(3):
        ranges = rng.uniform(0.1, 4.5, angles.size)
        ranges[rng.choice(angles.size, 6, replace=False)] = [np.inf, np.nan, 0.0, 5.0, 0.02, 9.0]
        scan = _scan(ranges, angles, range_min=0.05, range_max=5.0)
        pose = np.array([rng.uniform(0.0, 7.0), rng.uniform(3.0, 7.0), rng.uniform(-np.pi, np.pi)])
        hits, visits = (_f(a) for a in lab.counting_map_update(h0, v0, scan, pose, grid))
        dh, dv = np.zeros(grid.shape), np.zeros(grid.shape)
        start = grid.world_to_map(pose[:2])[::-1]
        for r, a in zip(ranges, angles, strict=True):
            if np.isnan(r) or r < 0.05:
                continue
            hit = r < 5.0
            end_xy = pose[:2] + min(r, 5.0) * np.array([np.cos(pose[2] + a), np.sin(pose[2] + a)])
            for c in _supercover(start, grid.world_to_map(end_xy)[::-1]):
                if grid.contains_cell(np.array(c)):
                    dv[c] += 1
            if hit:
                c = tuple(grid.world_to_cell(end_xy))
                if grid.contains_cell(np.array(c)):
                    dh[c] += 1
        np.testing.assert_array_equal(visits - v0, dv, err_msg=f"visits, trial {trial}")
        np.testing.assert_array_equal(hits - h0, dh, err_msg=f"hits, trial {trial}")


@pytest.mark.grades("counting_map_update", points=4)
def test_counting_update_invariants(lab):
    """Counts only grow, hits <= visits, the map stays in [0, 1], cells out of range untouched."""
    rng = np.random.default_rng(RNG_SEED + 2)
    grid = _grid(80, 100, 0.05, origin=(-1.0, -1.0, 0.0))
    hits = np.zeros(grid.shape)
    visits = np.zeros(grid.shape)
    pose = np.array([0.5, 0.5, 0.3])
    angles = np.linspace(-np.pi, np.pi, 90, endpoint=False)
    for _ in range(4):
        ranges = rng.uniform(0.0, 1.5, angles.size)
        ranges[::7] = np.inf
        new_h, new_v = (
            _f(a)
            for a in lab.counting_map_update(
                hits, visits, _scan(ranges, angles, 0.05, 1.0), pose, grid
            )
        )
        assert np.all(new_h >= hits) and np.all(new_v >= visits), "counts must never decrease"
        assert np.all(new_v - visits >= new_h - hits), "a hit is also a visit"
        occ = np.where(new_v > 0, new_h / np.maximum(new_v, 1), 0.0)
        assert np.all((occ >= 0) & (occ <= 1)), (
            "hits / visits must stay in [0, 1] in every visited cell"
        )
        hits, visits = new_h, new_v
    xs, ys = grid.cell_centers()
    far = np.hypot(xs - pose[0], ys - pose[1]) > 1.0 + 0.05 * np.sqrt(2)
    assert np.all(visits[far] == 0) and np.all(hits[far] == 0), (
        "cells beyond range_max must stay unseen"
    )
    assert visits[~far].sum() > 0, (
        "a scan of 90 beams from (0.5, 0.5) must visit some cell within range_max"
    )


@pytest.mark.grades("counting_map_update", points=2)
def test_counting_update_zero_reading_and_inputs_unchanged(lab):
    """A zero reading with range_min = 0 adds nothing.

    The hits and visits passed in are not modified.
    """
    grid = _grid(6, 6, 1.0)
    hits0, visits0 = np.ones((6, 6)), np.full((6, 6), 2.0)
    before = (hits0.copy(), visits0.copy())
    scan = _scan([0.0, 2.2], [np.pi / 2, 0.0], range_min=0.0, range_max=4.0)
    hits, visits = (
        _f(a)
        for a in lab.counting_map_update(hits0, visits0, scan, np.array([0.5, 0.5, 0.0]), grid)
    )
    exp_visits = visits0.copy()
    exp_visits[0, 0:3] += 1  # only the 2.2 m beam along row 0, ending in cell (0, 2)
    exp_hits = hits0.copy()
    exp_hits[0, 2] += 1
    np.testing.assert_array_equal(
        visits, exp_visits, err_msg="visits: a zero reading (range_min = 0) is invalid, no visit"
    )
    np.testing.assert_array_equal(
        hits, exp_hits, err_msg="hits: a zero reading (range_min = 0) is no hit at the laser"
    )
    np.testing.assert_array_equal(hits0, before[0], err_msg="the hits passed in were modified")
    np.testing.assert_array_equal(visits0, before[1], err_msg="the visits passed in were modified")


@pytest.mark.grades("counting_map_update", points=4)
@requires("test_counting_update_hand_computed", "test_counting_update_matches_supercover_counts")
def test_counting_map_wall_converges_to_occupied(lab):
    """A wall seen from 40 poses: its cells end up occupied, the space in front free."""
    rng = np.random.default_rng(RNG_SEED + 3)
    grid = _grid(100, 100, 0.05)
    wall_x = 4.025  # centre of column 80
    angles = np.linspace(-np.pi, np.pi, 180, endpoint=False)
    hits, visits = np.zeros(grid.shape), np.zeros(grid.shape)
    for k in range(40):
        pose = np.array([rng.uniform(0.5, 2.5), rng.uniform(1.5, 3.5), rng.uniform(-0.5, 0.5)])
        a = pose[2] + angles
        with np.errstate(divide="ignore"):
            r = (wall_x - pose[0]) / np.cos(a)
        y_hit = pose[1] + r * np.sin(a)
        ranges = np.where((np.cos(a) > 0.3) & (y_hit > 0.5) & (y_hit < 4.5), r, np.inf)
        hits, visits = (
            _f(x)
            for x in lab.counting_map_update(
                hits, visits, _scan(ranges, angles, 0.05, 8.0), pose, grid
            )
        )
        if k == 0:
            first_hits = hits.copy()
    wall = np.zeros(grid.shape[0], dtype=bool)
    wall[11:89] = visits[11:89, 80] >= 5  # the wall spans y in (0.5, 4.5): rows 10 to 89
    occ = hits[:, 80][wall] / visits[:, 80][wall]
    # Oblique beams cross a wall cell and end in its neighbour, so single cells can
    # dip below 0.5 (the reference: min 0.47, mean 0.83, 77 of 78 cells >= 0.5).
    assert wall.sum() >= 50 and np.mean(occ >= 0.5) >= 0.9 and occ.mean() > 0.7, (
        f"wall cells: {np.mean(occ >= 0.5):.0%} at or above 0.5, mean occupancy {occ.mean():.2f}"
    )
    front = visits[:, 10:78] > 0
    assert np.all(hits[:, 10:78][front] == 0), "no hit may land in front of the wall"
    assert (hits[:, 80] > 0).sum() > (first_hits[:, 80] > 0).sum(), (
        "more poses must reveal more of the wall"
    )


@pytest.fixture(scope="module")
def mapping_run():
    """Every 8th scan of data/mapping.bag, true and raw-odometry laser poses, the true map."""
    from robolab.bag import BagReader, laser_pose_in_base
    from robolab.raycast import cast_rays

    with BagReader(DATA_DIR / "mapping.bag") as bag:
        scans = bag.scans("/base_scan")
        odom = bag.odometry("/odom")
        truth = bag.odometry("/ground_truth")
        mount = laser_pose_in_base(bag.tf(), scans.frame_id)
    idx = np.arange(0, len(scans), 8)
    stamps = scans.stamps[idx]
    true_poses = truth.at(stamps)
    # raw odometry placed in the map frame at the known start pose (map -> odom)
    odom_poses = compose(truth.poses[np.argmin(truth.stamps)], odom.at(stamps))
    true_map = load_map(DATA_DIR / "office.yaml")
    # the walls the robot could see: where noise-free rays from the true laser poses end
    lp = compose(true_poses, mount)
    r = cast_rays(true_map, lp, scans.angles, scans.range_max)
    a = lp[:, 2:3] + scans.angles
    ok = r < scans.range_max
    pts = np.stack([lp[:, 0:1] + (r + 1e-6) * np.cos(a), lp[:, 1:2] + (r + 1e-6) * np.sin(a)], -1)[
        ok
    ]
    cells = true_map.world_to_cell(pts)
    cells = cells[true_map.contains_cell(cells)]
    visible = np.zeros(true_map.shape, dtype=bool)
    visible[cells[:, 0], cells[:, 1]] = True
    return {
        "scans": [
            _scan(scans.ranges[i], scans.angles, scans.range_min, scans.range_max) for i in idx
        ],
        "true_laser": lp,
        "odom_laser": compose(odom_poses, mount),
        "true_map": true_map,
        "visible_walls": visible & true_map.occupied,
    }


def _tolerant_iou(occupancy, true_map, visible_walls):
    """IoU of occupied cells with a one-cell (8-neighbour) tolerance.

    matched = predicted occupied cells within one cell of a true wall;
    missed = visible true wall cells with no predicted occupied cell within one cell;
    IoU = matched / (predicted + missed).
    """
    pred = occupancy >= 0.5
    ring = np.ones((3, 3), dtype=bool)
    near_true = ndimage.binary_dilation(true_map.occupied, ring)
    near_pred = ndimage.binary_dilation(pred, ring)
    matched = (pred & near_true).sum()
    missed = (visible_walls & ~near_pred).sum()
    return matched / max(pred.sum() + missed, 1)


@pytest.mark.grades("counting_map_update", points=5)
@requires("test_counting_update_hand_computed", "test_counting_update_matches_supercover_counts")
def test_counting_map_from_bag_truth_beats_raw_odometry(lab, mapping_run):
    """Bundled bag: true poses give IoU >= 0.8 with the true walls; raw odometry 0.4 less.

    Every 8th scan (100 scans), the map's geometry from data/office.yaml. IoU of
    occupied cells (occupancy >= 0.5) with a one-cell tolerance, see
    ``_tolerant_iou``; the reference solution scores about 0.92 (ground truth)
    and 0.16 (raw odometry).
    """
    true_map = mapping_run["true_map"]
    grid = true_map.with_data(np.full(true_map.shape, -1.0))
    iou = {}
    for key in ("true_laser", "odom_laser"):
        hits = np.zeros(grid.shape)
        visits = np.zeros(grid.shape)
        for scan, pose in zip(mapping_run["scans"], mapping_run[key], strict=True):
            hits, visits = (_f(a) for a in lab.counting_map_update(hits, visits, scan, pose, grid))
        occupancy = np.where(visits > 0, hits / np.maximum(visits, 1), -1.0)
        iou[key] = _tolerant_iou(occupancy, true_map, mapping_run["visible_walls"])
    assert iou["true_laser"] >= 0.8, (
        f"map from ground-truth poses: IoU {iou['true_laser']:.3f} < 0.8"
    )
    assert iou["odom_laser"] <= iou["true_laser"] - 0.4, (
        f"raw-odometry map IoU {iou['odom_laser']:.3f} should be far below the ground-truth map's "
        f"{iou['true_laser']:.3f}"
    )


# ------------------------------------------------------------------ occupancy_from_counts (5)


@pytest.mark.grades("occupancy_from_counts", points=3)
def test_occupancy_from_counts_values(lab):
    """hits / visits where visited, -1 where never visited."""
    hits = np.array([[0.0, 1.0, 3.0], [0.0, 0.0, 2.0]])
    visits = np.array([[0.0, 4.0, 3.0], [5.0, 0.0, 8.0]])
    got = _f(lab.occupancy_from_counts(hits, visits))
    np.testing.assert_allclose(
        got,
        [[-1.0, 0.25, 1.0], [0.0, -1.0, 0.25]],
        atol=1e-12,
        err_msg="hits [[0, 1, 3], [0, 0, 2]] over visits [[0, 4, 3], [5, 0, 8]]",
    )


@pytest.mark.grades("occupancy_from_counts", points=2)
@requires("test_occupancy_from_counts_values")
def test_occupancy_from_counts_bad_input(lab, refuses):
    """More hits than visits, negative counts or mismatched shapes raise ValueError."""
    with refuses(ValueError, "hits = 2 > visits = 1 (a cell hit more often than seen)"):
        lab.occupancy_from_counts(np.array([2.0]), np.array([1.0]))
    with refuses(ValueError, "hits = -1, a negative count"):
        lab.occupancy_from_counts(np.array([-1.0]), np.array([1.0]))
    with refuses(ValueError, "hits of shape (2, 2) and visits of shape (2, 3)"):
        lab.occupancy_from_counts(np.zeros((2, 2)), np.zeros((2, 3)))


# ------------------------------------------------------------------ clip_map (5)


@pytest.mark.grades("clip_map", points=3)
def test_clip_map_values(lab):
    """Below the threshold -> 0, at or above -> 1, unknown stays -1."""
    occ = np.array([[-1.0, 0.0, 0.2, 0.49999], [0.5, 0.51, 1.0, -1.0]])
    got = _f(lab.clip_map(occ))
    np.testing.assert_array_equal(
        got,
        [[-1.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, -1.0]],
        err_msg="clip_map at the default threshold 0.5 (0.5 -> 1, 0.49999 -> 0, -1 stays -1)",
    )
    got = _f(lab.clip_map(occ, threshold=0.8))
    np.testing.assert_array_equal(
        got, [[-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0]], err_msg="clip_map at threshold 0.8"
    )


@pytest.mark.grades("clip_map", points=2)
@requires("test_clip_map_values")
def test_clip_map_bad_input(lab, refuses):
    """Occupancy outside [0, 1] (except -1), NaN, or a threshold outside [0, 1]: ValueError."""
    with refuses(ValueError, "occupancy = (0.2, 1.5), a probability above 1"):
        lab.clip_map(np.array([0.2, 1.5]))
    with refuses(ValueError, "occupancy = (0.2, NaN)"):
        lab.clip_map(np.array([0.2, np.nan]))
    with refuses(ValueError, "threshold = 1.5, not a probability"):
        lab.clip_map(np.array([0.2, 0.7]), threshold=1.5)


# ------------------------------------------------------------------ logodds_update (20)

PARAMS = {"l_occ": 0.9, "l_free": -0.7, "l_0": 0.1, "alpha": 0.2, "beta": np.deg2rad(30.0)}


def _table_9_2(grid, scan, pose, params):
    """Table 9.1's increment per cell, transcribed cell by cell from Table 9.2 (a Python loop)."""
    ranges = np.asarray(scan["ranges"], dtype=float)
    angles = wrap_angle(np.asarray(scan["angles"], dtype=float))
    z_max = scan["range_max"]
    with np.errstate(invalid="ignore"):
        keep = (ranges > 0) & (ranges >= scan["range_min"])  # NaN compares False
    z = np.where(ranges >= z_max, z_max, ranges)[keep]
    theta_k = angles[keep]
    delta = np.zeros(grid.shape)
    xs, ys = grid.cell_centers()
    for i in range(grid.shape[0]):
        for j in range(grid.shape[1]):
            r = math.hypot(xs[i, j] - pose[0], ys[i, j] - pose[1])
            phi = wrap_angle(math.atan2(ys[i, j] - pose[1], xs[i, j] - pose[0]) - pose[2])
            diffs = np.abs(wrap_angle(phi - theta_k))
            k = int(np.argmin(diffs))
            if r > min(z_max, z[k] + params["alpha"] / 2) or diffs[k] > params["beta"] / 2:
                value = params["l_0"]
            elif z[k] < z_max and abs(r - z[k]) < params["alpha"] / 2:
                value = params["l_occ"]
            elif r <= z[k]:
                value = params["l_free"]
            else:
                value = params["l_0"]
            delta[i, j] = value - params["l_0"]
    return delta


@pytest.mark.grades("logodds_update", points=5)
def test_logodds_update_matches_table_9_2(lab):
    """One scan with hits, no-returns and invalid beams against a literal Table 9.2."""
    rng = np.random.default_rng(RNG_SEED + 4)
    grid = _grid(36, 44, 0.1, origin=(-1.2, -0.7, 0.0))
    angles = np.linspace(-np.pi, np.pi, 16, endpoint=False) + 0.01
    ranges = rng.uniform(0.4, 1.6, angles.size)
    ranges[[2, 7, 11, 13]] = [
        np.inf,
        np.nan,
        2.0,
        0.01,
    ]  # no return, invalid, = range_max, < range_min
    scan = _scan(ranges, angles, range_min=0.05, range_max=2.0)
    pose = np.array([0.93, 1.07, 0.4])
    prior = rng.normal(0.0, 1.0, grid.shape)
    got = _f(lab.logodds_update(prior, scan, pose, grid, PARAMS))
    expected = prior + _table_9_2(grid, scan, pose, PARAMS)
    assert got.shape == grid.shape, (
        "logodds_update must return an array of the grid's shape (36, 44)"
    )
    bad = ~np.isclose(got, expected, atol=1e-9)
    assert not bad.any(), (
        f"{bad.sum()} cells differ from Table 9.2, e.g. cell {tuple(np.argwhere(bad)[0])}: "
        f"expected {expected[bad][0]:.3f}, got {got[bad][0]:.3f}"
    )


@pytest.mark.grades("logodds_update", points=5)
def test_logodds_update_is_sum_of_evidence(lab):
    """Updates commute: any order of three scans gives prior + the sum of each scan's evidence."""
    rng = np.random.default_rng(RNG_SEED + 5)
    grid = _grid(40, 40, 0.1)
    angles = np.linspace(-np.pi, np.pi, 60, endpoint=False)
    scans = [_scan(rng.uniform(0.3, 2.5, angles.size), angles, 0.05, 2.0) for _ in range(3)]
    poses = [
        np.array([rng.uniform(1.0, 3.0), rng.uniform(1.0, 3.0), rng.uniform(-np.pi, np.pi)])
        for _ in range(3)
    ]
    prior = rng.normal(0.0, 0.5, grid.shape)
    zero = np.zeros(grid.shape)
    evidence = [
        _f(lab.logodds_update(zero, s, p, grid, PARAMS)) for s, p in zip(scans, poses, strict=True)
    ]
    assert any(np.any(e != 0) for e in evidence), "a scan must change some cells"
    for order in ([0, 1, 2], [2, 0, 1], [1, 2, 0]):
        l = prior.copy()  # noqa: E741
        for k in order:
            l = _f(lab.logodds_update(l, scans[k], poses[k], grid, PARAMS))  # noqa: E741
        np.testing.assert_allclose(l, prior + sum(evidence), atol=1e-9, err_msg=f"order {order}")


@pytest.mark.grades("logodds_update", points=3)
def test_logodds_update_single_beam_profile(lab):
    """One beam: free before z - alpha/2, occupied around z, untouched beyond; no return: free."""
    grid = _grid(1, 40, 0.1)
    params = {"l_occ": 2.0, "l_free": -1.0, "l_0": 0.0, "alpha": 0.3, "beta": 0.1}
    scan = _scan([2.0], [0.0], 0.05, 3.5)
    got = _f(
        lab.logodds_update(np.zeros(grid.shape), scan, np.array([0.0, 0.05, 0.0]), grid, params)
    )[0]
    x = (np.arange(40) + 0.5) * 0.1
    expected = np.where(np.abs(x - 2.0) < 0.15, 2.0, np.where(x <= 2.0, -1.0, 0.0))
    np.testing.assert_allclose(
        got,
        expected,
        atol=1e-12,
        err_msg="one beam of 2 m (alpha 0.3): -1 (free) before 1.85 m, +2 within 0.15 m of 2 m, "
        "0 beyond",
    )
    got = _f(
        lab.logodds_update(
            np.zeros(grid.shape),
            _scan([np.inf], [0.0], 0.05, 3.5),
            np.array([0.0, 0.05, 0.0]),
            grid,
            params,
        )
    )[0]
    np.testing.assert_allclose(
        got,
        np.where(x <= 3.5, -1.0, 0.0),
        atol=1e-12,
        err_msg="a no-return (inf) beam with range_max 3.5: free up to 3.5 m, never occupied",
    )


@pytest.mark.grades("logodds_update", points=3)
@requires("test_logodds_update_matches_table_9_2")
def test_logodds_update_table_9_2_at_headings_far_from_zero(lab):
    """A laser facing pi, pi/2 or -pi/2 maps like one facing 0 in the grid turned with it.

    Bearings atan2(...) - theta then cross +-pi and must be wrapped. Turning the
    whole world (grid and laser) by a multiple of pi/2 about the laser maps cells onto
    cells, so the evidence must be the same array turned, whatever the inverse sensor
    model's details: only unwrapped bearings fail here (Table 9.2 itself is checked
    above).
    """
    rng = np.random.default_rng(RNG_SEED + 6)
    res, (rows, cols), (ox, oy) = 0.1, (22, 26), (-1.23, -1.07)
    grid = _grid(rows, cols, res, origin=(ox, oy, 0.0))
    angles = np.linspace(-np.pi, np.pi, 24, endpoint=False) + 0.02
    ranges = rng.uniform(0.3, 1.3, angles.size)
    ranges[[4, 17]] = [np.inf, 1.5]  # no return, = range_max
    scan = _scan(ranges, angles, range_min=0.05, range_max=1.5)
    # the same world turned so that the laser (at the origin) faces 0
    turned = {
        np.pi: (
            _grid(rows, cols, res, origin=(-(ox + cols * res), -(oy + rows * res), 0.0)),
            lambda b: b[::-1, ::-1],
        ),
        np.pi / 2: (
            _grid(cols, rows, res, origin=(oy, -(ox + cols * res), 0.0)),
            lambda b: b[::-1, :].T,
        ),
        -np.pi / 2: (
            _grid(cols, rows, res, origin=(-(oy + rows * res), ox, 0.0)),
            lambda b: b[:, ::-1].T,
        ),
    }
    for heading, (grid_0, back) in turned.items():
        got = _f(
            lab.logodds_update(
                np.zeros(grid.shape), scan, np.array([0.0, 0.0, heading]), grid, PARAMS
            )
        )
        ref = back(
            _f(lab.logodds_update(np.zeros(grid_0.shape), scan, np.zeros(3), grid_0, PARAMS))
        )
        assert np.any(ref != 0), "test self-check: the scan must change some cells"
        bad = ~np.isclose(got, ref, atol=1e-9)
        assert not bad.any(), (
            f"laser heading {heading:.4f} rad: {bad.sum()} of {bad.size} cells differ from the "
            f"same "
            f"scan facing 0 in the turned grid, e.g. cell "
            f"{tuple(np.argwhere(bad)[0]) if bad.any() else None}: "
            f"expected {ref[bad][:1]}, got {got[bad][:1]} (are the bearings wrapped?)"
        )


@pytest.mark.grades("logodds_update", points=2)
@requires("test_logodds_update_matches_table_9_2", "test_logodds_update_single_beam_profile")
def test_logodds_update_zero_reading_and_input_unchanged(lab):
    """A zero reading with range_min = 0 is no information.

    The log-odds passed in are not modified.
    """
    grid = _grid(1, 30, 0.1)
    params = {"l_occ": 2.0, "l_free": -1.0, "l_0": 0.0, "alpha": 0.3, "beta": 0.1}
    prior = np.full(grid.shape, 0.25)
    before = prior.copy()
    scan = _scan([0.0], [0.0], range_min=0.0, range_max=2.5)
    got = _f(lab.logodds_update(prior, scan, np.array([0.0, 0.05, 0.0]), grid, params))
    np.testing.assert_allclose(
        got,
        before,
        atol=1e-12,
        err_msg="one beam reading 0 with range_min = 0: no cell may change (it is not a hit at "
        "the laser)",
    )
    scan = _scan([1.0], [0.0], range_min=0.0, range_max=2.5)
    lab.logodds_update(prior, scan, np.array([0.0, 0.05, 0.0]), grid, params)
    np.testing.assert_array_equal(
        prior, before, err_msg="logodds_update modified the log-odds passed in"
    )


@pytest.mark.grades("logodds_update", points=2)
@requires("test_logodds_update_matches_table_9_2", "test_logodds_update_single_beam_profile")
def test_logodds_update_bad_input(lab, refuses):
    """Missing parameters, alpha <= 0 and a log-odds array of the wrong shape raise ValueError."""
    grid = _grid(10, 10, 0.1)
    scan = _scan([0.5], [0.0], 0.05, 2.0)
    bad = dict(PARAMS)
    del bad["beta"]
    with refuses(ValueError, "inverse_sensor_model_params without 'beta'"):
        lab.logodds_update(np.zeros((10, 10)), scan, np.array([0.5, 0.5, 0.0]), grid, bad)
    with refuses(
        ValueError,
        "inverse_sensor_model_params with alpha = 0 (the obstacle thickness must be > 0)",
    ):
        lab.logodds_update(
            np.zeros((10, 10)), scan, np.array([0.5, 0.5, 0.0]), grid, {**PARAMS, "alpha": 0.0}
        )
    with refuses(ValueError, "logodds of shape (10, 11) for a 10 x 10 grid"):
        lab.logodds_update(np.zeros((10, 11)), scan, np.array([0.5, 0.5, 0.0]), grid, PARAMS)


# ------------------------------------------------------------------ logodds_to_probability (5)


@pytest.mark.grades("logodds_to_probability", points=3)
def test_logodds_to_probability_values(lab):
    """p = 1 - 1 / (1 + exp(l)), exact at hand-computed points and stable for huge |l|."""
    l = np.array([[0.0, np.log(3.0)], [-np.log(4.0), 2.0]])  # noqa: E741
    got = _f(lab.logodds_to_probability(l))
    np.testing.assert_allclose(
        got,
        [[0.5, 0.75], [0.2, 1 - 1 / (1 + np.exp(2.0))]],
        rtol=1e-12,
        err_msg="p = 1 - 1 / (1 + exp(l)) at l = 0, log 3, -log 4, 2",
    )
    big = _f(lab.logodds_to_probability(np.array([-800.0, 800.0, -40.0])))
    assert np.all(np.isfinite(big)), "no NaN or inf for large |l|"
    np.testing.assert_allclose(
        big,
        [0.0, 1.0, np.exp(-40.0)],
        rtol=1e-9,
        atol=0,
        err_msg="l = -800, 800, -40: 0, 1 and exp(-40) without overflow or cancellation",
    )


@pytest.mark.grades("logodds_to_probability", points=2)
def test_logodds_to_probability_inverts_logodds(lab):
    """Round trip: log(p / (1 - p)) of the result gives the log-odds back."""
    l = np.linspace(-12.0, 12.0, 97)  # noqa: E741
    p = _f(lab.logodds_to_probability(l))
    assert p.shape == l.shape and np.all(np.diff(p) > 0), (
        "p = logodds_to_probability(linspace(-12, 12)) must keep the shape and increase strictly"
    )
    np.testing.assert_allclose(
        np.log(p / (1 - p)),
        l,
        atol=1e-6,
        err_msg="round trip log(p / (1 - p)) = l for l in [-12, 12]",
    )
