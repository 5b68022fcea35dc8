"""Tests of robolab.raycast: analytic cases, a brute-force oracle, the lab API, bad input.

Every test runs once per backend (the compiled numba kernel, the numpy
fallback, and an "auto" caster on its numpy path for small work before numba
is loaded), through the ``backend`` fixture.
"""

from __future__ import annotations

import importlib.util
import weakref

import numpy as np
import pytest

from robolab import raycast
from robolab.maps import UNKNOWN, OccupancyGrid, load_map
from robolab.raycast import RayCaster, cast_rays, castrays, castraysingle


@pytest.fixture(autouse=True, params=[*raycast.BACKENDS, "octants"])
def backend(request, monkeypatch):
    """Run the test with casters of one backend (a fresh cache: no caster of the other leaks in).

    ``octants``: the numba backend with octant fields on every map (else only on large
    sparse ones); the test sees ``"numba"``.
    """
    if request.param == "octants":
        monkeypatch.setattr(raycast, "_OCTANT_MIN_CELLS", 0)
        monkeypatch.setattr(raycast, "_OCTANT_MAX_OCCUPIED", 1.0)
        request = type("Param", (), {"param": "numba"})()
    if request.param != "numpy" and raycast._jit() is None:
        if importlib.util.find_spec("numba") is not None:
            pytest.fail("numba is installed but the compiled ray caster did not load (see warning)")
        pytest.skip("numba is not installed")
    if request.param == "auto":
        # the small-work path of an "auto" caster: numba not loaded yet, budget left
        monkeypatch.setattr(raycast, "_JIT", False)
        monkeypatch.setitem(raycast._AUTO, "budget", float("inf"))
    monkeypatch.setattr(raycast, "default_backend", lambda: request.param)
    monkeypatch.setattr(raycast, "_CACHE", weakref.WeakKeyDictionary())
    monkeypatch.setenv("ROBOLAB_RAYCAST", request.param)  # for the subprocess tests
    return request.param


RIGHT, UP, LEFT, DOWN = 0.0, np.pi / 2, np.pi, -np.pi / 2
FOUR = [RIGHT, UP, LEFT, DOWN]


def box(h=10, w=10):
    """A free h x w grid closed by one-cell walls on its border."""
    data = np.zeros((h, w))
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 1.0
    return data


def single(grid, pose, angle, max_range=100.0):
    return float(cast_rays(grid, pose, [angle], max_range)[0, 0])


# -- hand-made cases ------------------------------------------------------------------------
def test_axis_aligned_in_all_four_directions():
    g = OccupancyGrid(box(), 1.0)
    # Walls: x in [0, 1] and [9, 10], y in [0, 1] and [9, 10].
    ranges = cast_rays(g, [3.5, 4.5, 0.0], FOUR, 100.0)
    np.testing.assert_allclose(ranges, [[5.5, 4.5, 2.5, 3.5]], atol=1e-12)
    # The beams are relative to the heading: turning the pose by +90 deg rotates the answers.
    turned = cast_rays(g, [3.5, 4.5, UP], FOUR, 100.0)
    np.testing.assert_allclose(turned, [[4.5, 2.5, 3.5, 5.5]], atol=1e-12)


def test_diagonal_at_45_degrees_has_the_analytic_length():
    # The line y = x + 0.3 from (1.2, 1.5) never passes through a cell corner.
    wall_x = np.zeros((10, 10))
    wall_x[:, 6] = 1.0  # x in [6, 7]: entered at x = 6
    wall_y = np.zeros((10, 10))
    wall_y[6, :] = 1.0  # y in [6, 7]: entered at y = 6, i.e. x = 5.7
    pose = [1.2, 1.5, np.pi / 4]
    assert single(OccupancyGrid(wall_x, 1.0), pose, 0.0) == pytest.approx(
        4.8 * np.sqrt(2), abs=1e-12
    )
    assert single(OccupancyGrid(wall_y, 1.0), pose, 0.0) == pytest.approx(
        4.5 * np.sqrt(2), abs=1e-12
    )


@pytest.mark.parametrize("eps", [1e-9, 1e-6])
def test_grazing_a_corner(eps):
    data = np.zeros((10, 10))
    data[5, 5] = 1.0  # the square [5, 6] x [5, 6]
    g = OccupancyGrid(data, 1.0)
    # Horizontal rays just below and just above the obstacle's bottom edge y = 5.
    assert single(g, [1.0, 5.0 - eps, 0.0], 0.0, 20.0) == 20.0
    assert single(g, [1.0, 5.0 + eps, 0.0], 0.0, 20.0) == pytest.approx(4.0, abs=1e-12)
    # A diagonal ray towards the corner (5, 5), shifted left (misses) or right
    # (enters through the bottom face).
    up_left = 3 * np.pi / 4
    assert single(g, [6.5 - eps, 3.5, up_left], 0.0, 20.0) == 20.0
    assert single(g, [6.5 + eps, 3.5, up_left], 0.0, 20.0) == pytest.approx(
        1.5 * np.sqrt(2), abs=1e-8
    )


def test_pose_inside_an_obstacle_returns_zero():
    data = np.zeros((10, 10))
    data[4, 4] = 1.0
    g = OccupancyGrid(data, 1.0)
    angles = np.linspace(-np.pi, np.pi, 13)
    np.testing.assert_array_equal(cast_rays(g, [4.5, 4.5, 0.3], angles, 5.0), 0.0)
    # The lower-left edges belong to the cell (as world_to_cell assigns them).
    np.testing.assert_array_equal(cast_rays(g, [4.0, 4.0, 0.0], angles, 5.0), 0.0)
    # A pose just outside, on the right edge, looking away: free path to max range.
    assert single(g, [5.0, 4.5, 0.0], 0.0, 3.0) == 3.0
    # ... and looking at the cell: touching it, range 0.
    assert single(g, [5.0, 4.5, 0.0], LEFT, 3.0) == 0.0


def test_leaving_the_map_returns_max_range():
    g = OccupancyGrid(np.zeros((10, 10)), 1.0)
    angles = np.linspace(-np.pi, np.pi, 37)
    np.testing.assert_array_equal(cast_rays(g, [3.3, 6.1, 0.2], angles, 50.0), 50.0)
    # Obstacles only behind the pose do not matter.
    data = np.zeros((10, 10))
    data[:, 0] = 1.0
    assert single(OccupancyGrid(data, 1.0), [5.5, 5.5, 0.0], 0.0, 50.0) == 50.0


def test_max_range_in_free_space():
    g = OccupancyGrid(box(), 1.0)
    ranges = cast_rays(g, [3.5, 4.5, 0.0], FOUR, 3.0)  # walls at 5.5, 4.5, 2.5, 3.5
    np.testing.assert_allclose(ranges, [[3.0, 3.0, 2.5, 3.0]], atol=1e-12)


def test_unknown_cells_are_not_obstacles():
    data = box()
    data[1:-1, 5:7] = UNKNOWN
    data[3:6, 2] = 0.4  # below the occupancy threshold 0.5: free
    g = OccupancyGrid(data, 1.0)
    assert single(g, [1.5, 4.5, 0.0], 0.0) == pytest.approx(7.5, abs=1e-12)
    # With a lower threshold the 0.4 cells become obstacles.
    g2 = OccupancyGrid(data, 1.0, occupied_threshold=0.3)
    assert single(g2, [1.5, 4.5, 0.0], 0.0) == pytest.approx(0.5, abs=1e-12)


def test_resolution_and_offset_origin():
    # The box scaled to 0.25 m cells and moved so that its corner is at (-2, 3).
    g = OccupancyGrid(box(), 0.25, origin=[-2.0, 3.0, 0.0])
    pose = [-2.0 + 3.5 * 0.25, 3.0 + 4.5 * 0.25, 0.0]
    np.testing.assert_allclose(
        cast_rays(g, pose, FOUR, 100.0),
        [[5.5 * 0.25, 4.5 * 0.25, 2.5 * 0.25, 3.5 * 0.25]],
        atol=1e-12,
    )


def test_rotated_origin():
    # Map x points along world +y: a wall at map x in [8, 9] is at world y in [8, 9].
    data = np.zeros((10, 10))
    data[:, 8] = 1.0
    g = OccupancyGrid(data, 1.0, origin=[0.0, 0.0, np.pi / 2])
    pose_world = [-5.5, 2.5, UP]  # map point (2.5, 5.5), heading along map +x
    assert single(g, pose_world, 0.0) == pytest.approx(5.5, abs=1e-12)
    assert single(g, pose_world, np.pi, 20.0) == 20.0


def test_pose_outside_the_map_is_traced_from_where_the_ray_enters():
    data = np.zeros((10, 10))
    data[:, 8] = 1.0
    g = OccupancyGrid(data, 1.0)
    assert single(g, [-2.5, 5.5, 0.0], 0.0) == pytest.approx(10.5, abs=1e-12)
    assert single(g, [-2.5, 5.5, 0.0], LEFT, 30.0) == 30.0
    assert single(g, [-2.5, 5.5, 0.0], 0.0, 10.0) == 10.0  # the wall is beyond max_range


def test_shapes():
    g = OccupancyGrid(box(), 1.0)
    assert cast_rays(g, [3.5, 4.5, 0.0], FOUR, 9.0).shape == (1, 4)
    poses = np.array([[3.5, 4.5, 0.0], [2.5, 2.5, 1.0], [7.5, 7.5, -2.0]])
    out = cast_rays(g, poses, FOUR, 9.0)
    assert out.shape == (3, 4)
    # Each row is what that pose gives alone.
    for i in range(3):
        np.testing.assert_array_equal(out[i], cast_rays(g, poses[i], FOUR, 9.0)[0])
    assert cast_rays(g, poses, [], 9.0).shape == (3, 0)
    assert cast_rays(g, np.zeros((0, 3)), FOUR, 9.0).shape == (0, 4)


def test_grid_is_immutable_and_with_data_sees_new_obstacles():
    g = OccupancyGrid(box(), 1.0)
    assert single(g, [3.5, 4.5, 0.0], 0.0) == pytest.approx(5.5)
    with pytest.raises(ValueError):  # the cached distance field can never go stale
        g.data[4, 6] = 1.0
    data = np.array(g.data)
    data[4, 6] = 1.0
    assert single(g.with_data(data), [3.5, 4.5, 0.0], 0.0) == pytest.approx(2.5)
    assert single(g, [3.5, 4.5, 0.0], 0.0) == pytest.approx(5.5)


# -- oracle: fine steps along every ray -------------------------------------------------------
def fine_step_oracle(grid, poses, angles, max_range, step):
    """First sample ``k * step`` whose cell (by grid.world_to_cell) is an in-map obstacle."""
    ts = np.arange(0.0, max_range, step)
    phi = poses[:, 2:3] + np.asarray(angles)[None, :]  # (N, B)
    out = np.full(phi.shape, float(max_range))
    occ = grid.occupied
    for i in range(poses.shape[0]):  # loop over poses only; beams and steps are vectorized
        d = np.stack([np.cos(phi[i]), np.sin(phi[i])], -1)  # (B, 2)
        pts = poses[i, None, None, :2] + ts[None, :, None] * d[:, None, :]  # (B, T, 2)
        rc = grid.world_to_cell(pts)
        inside = grid.contains_cell(rc)
        hit = np.zeros(inside.shape, dtype=bool)
        hit[inside] = occ[rc[inside][:, 0], rc[inside][:, 1]]
        first = np.argmax(hit, axis=1)
        found = hit[np.arange(hit.shape[0]), first]
        out[i, found] = ts[first[found]]
    return out


@pytest.mark.parametrize("seed", range(4))
def test_random_maps_against_a_fine_step_oracle(seed):
    rng = np.random.default_rng(seed)
    h, w = rng.integers(8, 25, size=2)
    data = (rng.random((h, w)) < rng.uniform(0.05, 0.35)).astype(float)
    data[rng.random((h, w)) < 0.1] = UNKNOWN
    res = rng.uniform(0.05, 0.5)
    origin = [rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-np.pi, np.pi)]
    g = OccupancyGrid(data, res, origin=origin)
    # Poses over the map and a margin around it (some outside, some inside obstacles).
    cells = np.stack([rng.uniform(-2, h + 2, 40), rng.uniform(-2, w + 2, 40)], -1)
    xy = g.cell_to_world(cells - 0.5)
    poses = np.column_stack([xy, rng.uniform(-np.pi, np.pi, 40)])
    angles = rng.uniform(-np.pi, np.pi, 25)
    max_range = res * max(h, w) * 0.8
    step = res / 200
    got = cast_rays(g, poses, angles, max_range)
    want = fine_step_oracle(g, poses, angles, max_range, step)
    # The exact entry point lies between the oracle's last free sample and its first
    # hit, so the oracle is at most one step long and never short ...
    diff = want - got
    assert np.all(diff >= -1e-9), np.abs(diff).max()
    # ... except where a ray clips an obstacle's corner along a chord shorter than the
    # step, which the oracle steps over. For those, check directly that the point just
    # past the reported range (1e-9 cells, far above float error) is in an obstacle.
    clipped = diff > step + 1e-9
    assert clipped.mean() < 0.01  # corner clips are rare; a real bug would show widely
    i, j = np.nonzero(clipped)
    phi = poses[i, 2] + angles[j]
    past = poses[i, :2] + (got[i, j] + 1e-9 * res)[:, None] * np.stack(
        [np.cos(phi), np.sin(phi)], -1
    )
    rc = g.world_to_cell(past)
    assert np.all(g.contains_cell(rc)) and np.all(g.occupied[rc[:, 0], rc[:, 1]])
    assert np.all((got >= 0) & (got <= max_range))


def test_maze_ranges_end_at_an_obstacle():
    """On the bundled maze: just past a range < max_range is an obstacle, just before is not."""
    from robolab.maps import load_maze

    g = load_maze()
    rng = np.random.default_rng(7)
    free = np.argwhere(g.free)
    xy = g.cell_to_world(free[rng.integers(len(free), size=200)])
    poses = np.column_stack([xy, rng.uniform(-np.pi, np.pi, 200)])
    angles = np.linspace(-np.pi / 2, np.pi / 2, 61)
    ranges = cast_rays(g, poses, angles, 4.0)
    assert np.all(ranges > 0) and np.all(ranges <= 4.0)
    phi = poses[:, 2:3] + angles
    d = np.stack([np.cos(phi), np.sin(phi)], -1)
    short = ranges < 4.0
    eps = 1e-6
    after = poses[:, None, :2] + (ranges + eps)[..., None] * d
    before = poses[:, None, :2] + (ranges - eps)[..., None] * d
    rc_after, rc_before = g.world_to_cell(after[short]), g.world_to_cell(before[short])
    assert np.all(g.occupied[rc_after[:, 0], rc_after[:, 1]])
    assert not np.any(g.occupied[rc_before[:, 0], rc_before[:, 1]])


# -- the lab API: pixel units, one code path ---------------------------------------------------
def test_castrays_is_cast_rays_in_pixel_units(tmp_path):
    from robolab.maze import write_maze

    yaml_path = write_maze(tmp_path)
    metres = load_map(yaml_path)
    pixels = load_map(tmp_path / "maze.png")  # resolution 1: pixel units
    res = metres.resolution
    rng = np.random.default_rng(3)
    thetas = np.linspace(-np.pi, np.pi, 61)
    for xc, yc in rng.uniform(5, 195, size=(5, 2)):
        px = castrays(xc, yc, thetas, pixels, 80.0)
        m = cast_rays(metres, [xc * res, yc * res, 0.0], thetas, 80.0 * res)[0]
        np.testing.assert_allclose(px * res, m, atol=1e-9)
        # A plain boolean array (grid convention) gives the same ranges as the grid.
        np.testing.assert_array_equal(castrays(xc, yc, thetas, pixels.occupied, 80.0), px)
        one = castraysingle(xc, yc, thetas[7], pixels, 80.0)
        assert isinstance(one, float) and one == px[7]
    # A grid in metres passed to the lab API is used in pixel units too.
    np.testing.assert_array_equal(
        castrays(50.5, 30.5, thetas, metres, 80.0), castrays(50.5, 30.5, thetas, pixels, 80.0)
    )


def test_castraysingle_hand_case_and_in_place_array_change():
    occ = np.zeros((10, 10), dtype=bool)
    occ[:, 8] = True
    assert castraysingle(2.5, 5.5, 0.0, occ, 20) == pytest.approx(5.5)
    assert castraysingle(2.5, 5.5, np.pi / 2, occ, 3) == 3.0
    occ[5, 4] = True  # the pixel-grid cache must notice
    assert castraysingle(2.5, 5.5, 0.0, occ, 20) == pytest.approx(1.5)
    assert castraysingle(2.5, 5.5, 0.0, occ.astype(int).tolist(), 20) == pytest.approx(1.5)


# -- bad input ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"grid": np.zeros((5, 5))}, TypeError, "grid"),
        ({"poses": [1.0, 2.0]}, ValueError, "poses"),
        ({"poses": np.zeros((4, 2))}, ValueError, "poses"),
        ({"poses": [np.nan, 1.0, 0.0]}, ValueError, "poses"),
        ({"poses": "abc"}, TypeError, "poses"),
        ({"angles": np.zeros((2, 2))}, ValueError, "angles"),
        ({"angles": [0.0, np.inf]}, ValueError, "angles"),
        ({"max_range": 0.0}, ValueError, "max_range"),
        ({"max_range": -1.0}, ValueError, "max_range"),
        ({"max_range": np.nan}, ValueError, "max_range"),
        ({"max_range": "far"}, TypeError, "max_range"),
    ],
)
def test_cast_rays_bad_input(kwargs, error, match):
    args = {
        "grid": OccupancyGrid(box(), 1.0),
        "poses": [3.5, 4.5, 0.0],
        "angles": [0.0],
        "max_range": 5.0,
    }
    args.update(kwargs)
    with pytest.raises(error, match=match):
        cast_rays(**args)


def test_lab_api_bad_input():
    occ = np.zeros((10, 10))
    with pytest.raises(ValueError, match="map"):
        castrays(1.0, 1.0, [0.0], np.zeros((3, 3, 3)), 5.0)
    with pytest.raises(ValueError, match="lidarrange"):
        castrays(1.0, 1.0, [0.0], occ, -5.0)
    with pytest.raises(TypeError, match="xc"):
        castraysingle("a", 1.0, 0.0, occ, 5.0)
    with pytest.raises(ValueError, match="theta"):
        castraysingle(1.0, 1.0, np.nan, occ, 5.0)
    with pytest.raises(ValueError, match="thetas"):
        castrays(1.0, 1.0, np.zeros((2, 2)), occ, 5.0)
    with pytest.raises(ValueError, match="data"):
        castrays(1.0, 1.0, [0.0], np.full((4, 4), 2.0), 5.0)
    with pytest.raises(TypeError, match="grid"):
        RayCaster("maze")


def test_distance_field_is_cached_per_grid():
    from robolab.raycast import _caster_for

    g = OccupancyGrid(box(), 1.0)
    assert _caster_for(g) is _caster_for(g)
    assert _caster_for(g.with_data(g.data)) is not _caster_for(g)


def _cast_in_subprocess(code: str, timeout: float = 60.0) -> str:
    # A hang must fail the test, not block the suite: run it in a child with a timeout
    # (ROBOLAB_RAYCAST, set by the backend fixture, picks the child's backend).
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_rays_starting_on_cell_boundaries_along_grid_lines_terminate():
    # Regression: a ray starting exactly on a row boundary with sin(-pi) ~ -1e-16 used
    # to loop for ever next to an obstacle (a jump of 0 recomputed the cell it left).
    out = _cast_in_subprocess(
        "import numpy as np\n"
        "from robolab.maps import OccupancyGrid\n"
        "from robolab.raycast import cast_rays\n"
        "d = np.zeros((10, 10)); d[:, 1] = 1\n"
        "print(float(cast_rays(OccupancyGrid(d, 1.0), [5.5, 5.0, 0.0], [-np.pi], 20.0)[0, 0]))\n"
    )
    assert float(out) == pytest.approx(3.5)


@pytest.mark.parametrize("seed", range(3))
def test_integer_poses_and_axis_or_diagonal_beams_match_the_oracle(seed):
    # Poses on cell corners and edges, beams at multiples of 45 degrees: every degenerate
    # tie the traversal can meet. The oracle samples just off the start to pick a side.
    rng = np.random.default_rng(seed)
    data = (rng.random((12, 12)) < 0.25).astype(float)
    g = OccupancyGrid(data, 1.0)
    corners = rng.integers(0, 13, size=(30, 2)).astype(float)
    halves = corners + rng.choice([0.0, 0.5], size=(30, 2))
    poses = np.column_stack([np.vstack([corners, halves]), np.zeros(60)])
    angles = np.arange(8) * np.pi / 4
    got = cast_rays(g, poses, angles, 30.0)
    assert np.all(np.isfinite(got)) and np.all((got >= 0) & (got <= 30.0))
    # Where the start is unambiguous (inside a cell and free), agree with the oracle.
    inside = (poses[:, 0] % 1 != 0) & (poses[:, 1] % 1 != 0)
    start = g.world_to_cell(poses[:, :2])
    ok = inside & g.contains_cell(start)
    ok[ok] &= ~g.occupied[start[ok, 0], start[ok, 1]]
    want = fine_step_oracle(g, poses[ok], angles[::2], 30.0, 1e-3)  # axis beams: no corner ties
    np.testing.assert_allclose(got[ok][:, ::2], want, atol=2e-3)


# -- the quadrant jump fields -------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(3))
def test_quadrant_field_matches_brute_force(seed):
    from robolab.raycast import _OBSTACLE, _quadrant_field

    rng = np.random.default_rng(seed)
    occ = rng.random((23, 31)) < rng.uniform(0.01, 0.1)
    cap = 7
    code = _quadrant_field(occ, cap)
    rr, cc = np.nonzero(occ)
    for r in range(occ.shape[0]):
        for c in range(occ.shape[1]):
            if occ[r, c]:
                assert code[r, c] == _OBSTACLE
                continue
            ahead = (rr >= r) & (cc >= c)
            s = np.hypot(np.maximum(rr[ahead] - r - 1, 0), np.maximum(cc[ahead] - c - 1, 0))
            s = min(s.min() if s.size else np.inf, cap)
            assert code[r, c] == np.floor(4 * s + 1e-9), (r, c)  # quarter cells, rounded down


def _exact_ray(occ, u0, v0, phi, limit):
    """One ray, plain Amanatides-Woo in cells (the benchmark's baseline), for poses in the map."""
    h, w = occ.shape
    dx, dy = np.cos(phi), np.sin(phi)
    c, r = int(np.floor(u0)), int(np.floor(v0))
    sx, sy = (1 if dx >= 0 else -1), (1 if dy >= 0 else -1)
    tx = ((c + (dx >= 0)) - u0) / dx if dx else np.inf
    ty = ((r + (dy >= 0)) - v0) / dy if dy else np.inf
    tdx, tdy = (abs(1 / dx) if dx else np.inf), (abs(1 / dy) if dy else np.inf)
    t = 0.0
    while t < limit:
        if not (0 <= r < h and 0 <= c < w):
            return limit
        if occ[r, c]:
            return t
        if tx < ty:
            t, c, tx = tx, c + sx, tx + tdx
        else:
            t, r, ty = ty, r + sy, ty + tdy
    return limit


def test_long_jumps_on_a_box_map_match_the_exact_traversal():
    # Long rays through open space and along box sides: the quadrant fields' jumps
    # (up to the cap) must never skip an obstacle cell. Poses inside the map.
    rng = np.random.default_rng(11)
    occ = np.zeros((300, 300), dtype=bool)
    for r, c, hh, ww in zip(
        *rng.integers(0, 300, (2, 60)), *rng.integers(2, 25, (2, 60)), strict=True
    ):
        occ[r : r + hh, c : c + ww] = True
    g = OccupancyGrid(occ.astype(float), 1.0)
    free = np.argwhere(~occ)[rng.integers(int((~occ).sum()), size=60)]
    uv = free[:, ::-1] + rng.uniform(0, 1, (60, 2))
    poses = np.column_stack([uv, rng.uniform(-np.pi, np.pi, 60)])
    # Random beams plus exactly axis-parallel and diagonal ones.
    angles = np.concatenate([rng.uniform(-np.pi, np.pi, 40), np.arange(8) * np.pi / 4])
    got = cast_rays(g, poses, angles, 250.0)
    want = np.array([[_exact_ray(occ, u, v, th + a, 250.0) for a in angles] for u, v, th in poses])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


# -- the two backends, the compiled fields, huge ranges -----------------------------------------
def test_caster_reports_its_backend(backend):
    g = OccupancyGrid(box(), 1.0)
    assert raycast._caster_for(g).backend == backend
    assert RayCaster(g, backend="numpy").backend == "numpy"
    with pytest.raises(ValueError, match="backend"):
        RayCaster(g, backend="cuda")


@pytest.mark.parametrize("seed", range(3))
def test_backends_agree(seed, backend):
    # Cluttered maps with unknown cells, rotated origin, poses in and around the map,
    # plus axis-parallel and diagonal beams: the compiled and numpy paths give the same
    # ranges (they differ only in float round-off).
    if raycast._jit() is None:
        pytest.skip("numba is not installed")
    rng = np.random.default_rng(100 + seed)
    h, w = rng.integers(20, 120, size=2)
    data = (rng.random((h, w)) < rng.uniform(0.01, 0.3)).astype(float)
    data[rng.random((h, w)) < 0.1] = UNKNOWN
    g = OccupancyGrid(data, 0.1, origin=[1.0, -2.0, rng.uniform(-np.pi, np.pi)])
    cells = np.stack([rng.uniform(-5, h + 5, 200), rng.uniform(-5, w + 5, 200)], -1)
    poses = np.column_stack([g.cell_to_world(cells - 0.5), rng.uniform(-np.pi, np.pi, 200)])
    angles = np.concatenate([rng.uniform(-np.pi, np.pi, 30), np.arange(8) * np.pi / 4])
    a = RayCaster(g, backend="numba").cast(poses, angles, 8.0)
    b = RayCaster(g, backend="numpy").cast(poses, angles, 8.0)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)


@pytest.mark.parametrize("n_poses, n_beams", [(1, 1), (1, 3), (1, 5), (2, 3), (3, 7), (11, 1)])
def test_rays_in_flight_each_report_into_their_own_slot(n_poses, n_beams, backend):
    # The compiled kernel traces a few rays at a time and refills a lane as soon as its
    # ray ends; with fewer rays than lanes, rays that miss the map between rays that hit,
    # and rays of very different lengths, every range must still land at its own (pose,
    # beam): the same as casting that ray alone.
    rng = np.random.default_rng(n_poses * 10 + n_beams)
    data = (rng.random((40, 60)) < 0.05).astype(float)
    g = OccupancyGrid(data, 0.25, origin=[-1.0, 2.0, 0.3])
    # alternate poses on the map and poses beside it (most of their beams miss the map)
    cells = rng.uniform([0, 0], [40, 60], (n_poses, 2))
    cells[1::2] += [0.0, 100.0]
    poses = np.column_stack([g.cell_to_world(cells - 0.5), rng.uniform(-np.pi, np.pi, n_poses)])
    angles = rng.uniform(-np.pi, np.pi, n_beams)
    together = cast_rays(g, poses, angles, 12.0)
    alone = np.array([[single(g, p, a, 12.0) for a in angles] for p in poses])
    np.testing.assert_allclose(together, alone, rtol=0, atol=1e-12)
    assert (together < 12.0).any() or n_poses * n_beams < 3, "no ray hit: the case tests nothing"


def test_poses_on_the_map_edge_agree_between_backends(backend):
    # Poses exactly on the map's lower or left edge (inside the map, half-open) with
    # beams pointing out of it leave the map at t = 0, also from an obstacle cell; poses
    # on the upper or right edge are off the map. Both backends must say the same.
    if raycast._jit() is None:
        pytest.skip("numba is not installed")
    data = np.zeros((6, 8))
    data[0, :] = data[:, 0] = 1.0  # obstacles along the lower and left edges
    data[3, 5] = 1.0
    g = OccupancyGrid(data, 0.5)
    edge = [(0.0, 1.3), (1.7, 0.0), (0.0, 0.0), (4.0, 1.1), (2.2, 3.0), (4.0, 3.0)]
    poses = np.array([(x, y, th) for x, y in edge for th in (0.0, 0.4)])
    angles = np.concatenate([np.arange(8) * np.pi / 4, np.linspace(-3.1, 3.1, 13)])
    a = RayCaster(g, backend="numba").cast(poses, angles, 5.0)
    b = RayCaster(g, backend="numpy").cast(poses, angles, 5.0)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def _field_test_grid(seed, small, large):
    """Random occupancy for the jump-field oracles: seed 0 a large grid sparse enough for
    distances past the exact one-byte range (127 cells), other seeds small and denser."""
    rng = np.random.default_rng(seed)
    shape = small if seed else large
    return rng.random(shape) < (rng.uniform(0.01, 0.15) if seed else 2e-4)


@pytest.mark.parametrize("seed", range(3))
def test_chessboard_quadrant_fields_match_brute_force(seed):
    if raycast._jit() is None:
        pytest.skip("numba is not installed")
    from robolab._raycast_jit import DECODE, FIELD_MAX, quadrant_fields

    occ = _field_test_grid(seed, (17, 29), (160, 300))
    fields = quadrant_fields(occ)
    assert fields.shape == (4, *occ.shape) and fields.dtype == np.uint8
    rr, cc = np.nonzero(occ)
    step = int(np.diff(DECODE[-2:])[0])
    for q, (sx, sy) in enumerate([(1, 1), (-1, 1), (1, -1), (-1, -1)]):
        for r in range(0, occ.shape[0], 1 if seed else 7):
            for c in range(0, occ.shape[1], 1 if seed else 5):
                di, dj = sy * (rr - r), sx * (cc - c)
                ahead = (di >= 0) & (dj >= 0)
                # the outside of the map counts as free
                d = np.maximum(di[ahead], dj[ahead]).min() if ahead.any() else np.inf
                got = DECODE[fields[q, r, c]]
                assert (got == 0) == bool(occ[r, c]), (q, r, c)
                # a lower bound (never a jump past an obstacle), exact below 128 cells
                # and within one code step of it up to FIELD_MAX
                assert got <= d, (q, r, c)
                assert got == d if d < 128 else got > min(d, FIELD_MAX) - step, (q, r, c)


@pytest.mark.parametrize("seed", range(3))
def test_octant_fields_match_brute_force(seed, backend):
    if backend != "numba":
        pytest.skip("the compiled fields: once per numba run")
    from robolab._raycast_jit import DECODE, FIELD_MAX, octant_fields

    occ = _field_test_grid(seed, (19, 27), (150, 290))
    fields = octant_fields(occ)
    assert fields.shape == (8, *occ.shape) and fields.dtype == np.uint8
    rr, cc = np.nonzero(occ)
    step = int(np.diff(DECODE[-2:])[0])
    for q in range(8):
        sx, sy, steep = (-1 if q & 1 else 1), (-1 if q & 2 else 1), q >= 4
        for r in range(0, occ.shape[0], 1 if seed else 7):
            for c in range(0, occ.shape[1], 1 if seed else 5):
                a, b = sy * (rr - r), sx * (cc - c)  # rows and columns ahead
                if steep:
                    a, b = b, a
                wedge = (b >= 0) & (a >= 0) & (a <= b + 1)
                e = b[wedge].min() if wedge.any() else np.inf
                quad = (a >= 0) & (b >= 0)
                d = np.maximum(a[quad], b[quad]).min() if quad.any() else np.inf
                want = max(e, d, 1)
                got = DECODE[fields[q, r, c]]
                assert (got == 0) == bool(occ[r, c]), (q, r, c)
                if occ[r, c]:
                    continue
                assert got <= want, (q, r, c)
                assert got == want if want < 128 else got > min(want, FIELD_MAX) - step, (q, r, c)


def test_octants_are_chosen_for_large_sparse_maps_only(backend):
    if backend != "numba" or raycast._OCTANT_MIN_CELLS == 0:
        pytest.skip("the rule itself: once, unpatched")
    sparse = np.zeros((800, 700), bool)
    sparse[::97, 5:60] = True
    assert raycast._use_octants(sparse)
    assert not raycast._use_octants(sparse[:300])  # small: quadrant fields fit in cache
    cluttered = np.random.default_rng(0).random((800, 700)) < 0.2
    assert not raycast._use_octants(cluttered)


def test_huge_max_range_is_returned_not_inf():
    # max_range / resolution overflows to inf for 1e308 m: rays that leave the map must
    # still return max_range, and hits their exact range.
    g = OccupancyGrid(box(), 0.5)
    angles = np.linspace(-np.pi, np.pi, 17)
    huge = cast_rays(g, [2.2, 2.6, 0.1], angles, 1e308)
    ref = cast_rays(g, [2.2, 2.6, 0.1], angles, 1e6)
    np.testing.assert_array_equal(huge, ref)  # a closed box: every beam hits
    out = cast_rays(OccupancyGrid(np.zeros((4, 4)), 0.5), [1.0, 1.0, 0.0], angles, 1e308)
    np.testing.assert_array_equal(out, 1e308)


def test_environment_selects_the_backend():
    code = "from robolab import raycast\nprint(raycast.default_backend())\n"
    import os
    import subprocess
    import sys

    env = {**os.environ, "ROBOLAB_RAYCAST": "numpy"}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert run.returncode == 0 and run.stdout.strip() == "numpy", run.stderr
    env["ROBOLAB_RAYCAST"] = "gpu"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert run.returncode != 0 and "ROBOLAB_RAYCAST" in run.stderr


def test_without_numba_the_numpy_fallback_is_used():
    # numba made unimportable in a child: cast_rays still works, on the numpy path, and
    # says so once the "auto" rule wants the compiled path (here: no numpy budget).
    code = (
        "import sys, warnings\n"
        "sys.modules['numba'] = None\n"
        "import numpy as np\n"
        "from robolab import raycast\n"
        "from robolab.maps import OccupancyGrid\n"
        "raycast._AUTO['budget'] = 0.0\n"
        "g = OccupancyGrid(np.eye(5), 1.0)\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    r = raycast.cast_rays(g, [0.5, 3.5, 0.0], [0.0], 9.0)\n"
        "print(raycast._caster_for(g).last_path, float(r[0, 0]),"
        " any('numpy fallback' in str(w.message) for w in caught),"
        " raycast.RayCaster(g).backend)\n"
    )
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "ROBOLAB_RAYCAST"}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["numpy", "2.5", "True", "numpy"]


def test_reference_casts_are_the_numpy_backend_bit_for_bit():
    # robolab data generates files with cast_rays_reference: it must not depend on numba.
    rng = np.random.default_rng(9)
    g = OccupancyGrid((rng.random((30, 40)) < 0.1).astype(float), 0.1, origin=[0.3, -0.2, 0.4])
    poses = np.column_stack([rng.uniform(0, 3, (50, 2)), rng.uniform(-np.pi, np.pi, 50)])
    angles = np.linspace(-np.pi, np.pi, 19)
    ref = raycast.cast_rays_reference(g, poses, angles, 2.5)
    assert raycast._caster_for(g, reference=True).backend == "numpy"
    np.testing.assert_array_equal(ref, RayCaster(g, backend="numpy").cast(poses, angles, 2.5))
    np.testing.assert_allclose(ref, cast_rays(g, poses, angles, 2.5), rtol=0, atol=1e-9)


def test_long_rays_on_a_sparse_map_match_the_exact_traversal():
    # Jumps of hundreds of cells (past the one-byte codes' exact range of 127 cells and
    # across their 32-cell rounding) must still stop at the first obstacle entered.
    rng = np.random.default_rng(12)
    occ = np.zeros((640, 700), dtype=bool)
    occ[rng.integers(0, 640, 120), rng.integers(0, 700, 120)] = True  # scattered cells
    occ[300:303, 100:600] = True  # a long thin wall
    g = OccupancyGrid(occ.astype(float), 1.0)
    free = np.argwhere(~occ)[rng.integers(int((~occ).sum()), size=20)]
    uv = free[:, ::-1] + rng.uniform(0, 1, (20, 2))
    poses = np.column_stack([uv, rng.uniform(-np.pi, np.pi, 20)])
    angles = np.concatenate([rng.uniform(-np.pi, np.pi, 8), [0.0, np.pi / 2, np.pi, -np.pi / 2]])
    got = cast_rays(g, poses, angles, 900.0)
    want = np.array([[_exact_ray(occ, u, v, th + a, 900.0) for a in angles] for u, v, th in poses])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    assert np.any((want > 200) & (want < 900))  # long hits were exercised


# -- "auto": numpy for small work, numba once it pays ------------------------------------------
def test_auto_caster_switches_to_numba_once_its_numpy_budget_is_spent(backend, monkeypatch):
    if backend != "auto":
        pytest.skip("one run is enough: the test sets the rule's state itself")
    rng = np.random.default_rng(5)
    data = (rng.random((40, 50)) < 0.08).astype(float)
    data[rng.random((40, 50)) < 0.2] = UNKNOWN
    g = OccupancyGrid(data, 0.1, origin=[0.2, -0.1, 0.3])
    poses = np.column_stack([rng.uniform(-0.5, 5.5, (40, 2)), rng.uniform(-np.pi, np.pi, 40)])
    angles = np.linspace(-np.pi, np.pi, 23)
    monkeypatch.setitem(raycast._AUTO, "budget", 0.5)
    monkeypatch.setitem(raycast._AUTO, "numpy_seconds", 0.0)
    caster = RayCaster(g)
    assert caster.backend == "auto"
    small = caster.cast(poses, angles, 3.0)
    assert caster.last_path == "numpy" and raycast._AUTO["numpy_seconds"] > 0.0
    np.testing.assert_array_equal(small, RayCaster(g, backend="numpy").cast(poses, angles, 3.0))
    monkeypatch.setattr(raycast, "_JIT", False)  # (the numpy caster above did not load it)
    monkeypatch.setitem(raycast._AUTO, "numpy_seconds", 0.5)  # the budget is spent
    after = caster.cast(poses, angles, 3.0)
    assert caster.last_path == "numba"
    np.testing.assert_allclose(after, small, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(after, RayCaster(g, backend="numba").cast(poses, angles, 3.0))
    # a cast too big for the budget goes to numba at once, also on a fresh caster
    monkeypatch.setattr(raycast, "_JIT", False)
    monkeypatch.setitem(raycast._AUTO, "numpy_seconds", 0.0)
    monkeypatch.setattr(raycast, "_NUMPY_SECONDS_PER_RAY", 1.0)
    fresh = RayCaster(g)
    np.testing.assert_array_equal(fresh.cast(poses, angles, 3.0), after)
    assert fresh.last_path == "numba"


def test_a_fresh_process_casts_small_work_without_importing_numba(backend):
    if backend != "auto":
        pytest.skip("one run is enough (the child picks its own backend)")
    code = (
        "import sys\n"
        "import numpy as np\n"
        "from robolab import DATA_DIR\n"
        "from robolab.maps import load_map\n"
        "from robolab.raycast import RayCaster, cast_rays, castrays\n"
        "g = load_map(DATA_DIR / 'office.yaml')\n"
        "poses = np.array([[2.0, 3.0, 0.4], [5.5, 8.0, -2.0]])\n"
        "a = np.linspace(-np.pi, np.pi, 60, endpoint=False)\n"
        "z = cast_rays(g, poses, a, 10.0)\n"
        "one = castrays(31.5, 40.5, a, g.occupied, 200.0)\n"
        "print('numba' in sys.modules)\n"
        "c = RayCaster(g, backend='numba')\n"
        "print(np.abs(z - c.cast(poses, a, 10.0)).max() < 1e-9)\n"
    )
    import os

    env = {k: v for k, v in os.environ.items() if k != "ROBOLAB_RAYCAST"}
    import subprocess
    import sys

    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["False", "True"]
