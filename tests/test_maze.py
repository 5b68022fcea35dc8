"""Tests of robolab.maze and the bundled data/maze.png."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from PIL import Image
from scipy import ndimage

from robolab import DATA_DIR
from robolab.maps import load_map, load_maze
from robolab.maze import MAZE_RESOLUTION, generate_maze, write_maze


def maze(seed=0, nx=7, ny=5, cell=9, wall=2):
    return generate_maze(nx, ny, cell, wall, np.random.default_rng(seed))


def test_same_seed_same_maze_and_different_seeds_differ():
    np.testing.assert_array_equal(maze(1), maze(1))
    assert not np.array_equal(maze(1), maze(2))


def test_shape_and_closed_border():
    img = maze(nx=7, ny=5, cell=9, wall=2)
    assert img.dtype == bool and img.shape == (5 * 9 + 2, 7 * 9 + 2)
    for edge in (img[:2, :], img[-2:, :], img[:, :2], img[:, -2:]):
        assert edge.all()


@pytest.mark.parametrize("seed", range(5))
def test_maze_is_perfect_connected_with_a_tree_of_passages(seed):
    nx, ny, cell, wall = 8, 6, 7, 2
    img = maze(seed, nx, ny, cell, wall)
    # Every free pixel is reachable from every other (4-connectivity, as a robot moves).
    _, n_components = ndimage.label(~img)
    assert n_components == 1
    # Count the openings between neighbouring maze cells: a spanning tree has exactly
    # nx * ny - 1 of them (connected + that many edges = no loops: a perfect maze).
    mid = wall + (cell - wall) // 2  # a pixel row/column through the middle of a corridor
    east = [not img[r * cell + mid, (c + 1) * cell] for r in range(ny) for c in range(nx - 1)]
    south = [not img[(r + 1) * cell, c * cell + mid] for r in range(ny - 1) for c in range(nx)]
    assert sum(east) + sum(south) == nx * ny - 1


def test_generate_maze_bad_input():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="cell_px"):
        generate_maze(4, 4, 3, 3, rng)
    with pytest.raises(ValueError, match="n_cells_x"):
        generate_maze(0, 4, 10, 2, rng)
    with pytest.raises(TypeError, match="n_cells_y"):
        generate_maze(4, 4.5, 10, 2, rng)
    with pytest.raises(TypeError, match="rng"):
        generate_maze(4, 4, 10, 2, 42)


def test_write_maze_is_deterministic_and_map_server_compatible(tmp_path):
    a = write_maze(tmp_path / "a")
    b = write_maze(tmp_path / "b")
    assert a.name == "maze.yaml"
    assert (a.parent / "maze.png").read_bytes() == (b.parent / "maze.png").read_bytes()
    meta = yaml.safe_load(a.read_text())
    assert meta == {
        "image": "maze.png",
        "resolution": MAZE_RESOLUTION,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    with Image.open(a.parent / "maze.png") as im:
        assert im.mode == "L"
        pixels = np.array(im)
    assert set(np.unique(pixels)) == {0, 255}
    # Row 0 of the image is the top; the grid's row 0 is the bottom.
    grid = load_map(a)
    np.testing.assert_array_equal(grid.occupied, np.flipud(pixels == 0))
    # The bare PNG (pixel units) has the same occupancy as the map_server YAML.
    np.testing.assert_array_equal(load_map(a.parent / "maze.png").occupied, grid.occupied)
    assert grid.resolution == MAZE_RESOLUTION


@pytest.mark.skipif(not (DATA_DIR / "maze.yaml").is_file(), reason="bundled maze not generated")
def test_bundled_maze_is_what_the_generator_writes(tmp_path):
    write_maze(tmp_path)
    assert (DATA_DIR / "maze.png").read_bytes() == (tmp_path / "maze.png").read_bytes()
    g = load_maze()
    np.testing.assert_array_equal(g.occupied, load_map(DATA_DIR / "maze.png").occupied)
    # Everything that is not wall is known free (no unknown cells in the maze).
    assert np.all(g.occupied | g.free)
    # Corridors wide enough for the lab's robot: 17 px = 0.85 m between walls.
    assert g.shape == (203, 203) and g.width == pytest.approx(10.15)
