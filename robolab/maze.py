"""The maze generator behind the bundled ``data/maze.png`` (lab 02, the beam model).

A *perfect* maze (exactly one path between any two maze cells: the passages
form a spanning tree of the cell graph) is carved by randomized depth-first
search ("recursive backtracker") and drawn as a binary image with walls of a
fixed thickness. :func:`write_maze` saves it as an 8-bit grey PNG plus a ROS
map_server YAML so that :func:`robolab.maps.load_maze` returns it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from PIL import Image

from robolab.validation import check_rng

__all__ = ["generate_maze", "write_maze", "MAZE_SEED", "MAZE_RESOLUTION"]

#: Seed of the bundled maze; changing it changes ``data/maze.png``.
MAZE_SEED = 20240502
#: Metres per pixel of the bundled maze.
MAZE_RESOLUTION = 0.05
#: Layout of the bundled maze: 10 x 10 maze cells of 20 px (1 m) with 3 px
#: (0.15 m) walls -> 203 x 203 px (10.15 m square), corridors 17 px (0.85 m) wide.
_BUNDLED = {"n_cells_x": 10, "n_cells_y": 10, "cell_px": 20, "wall_px": 3}


def _check_int(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def generate_maze(n_cells_x: int, n_cells_y: int, cell_px: int, wall_px: int, rng) -> np.ndarray:
    """Draw a random perfect maze as a boolean wall image.

    The maze has ``n_cells_x`` x ``n_cells_y`` cells on a lattice of pitch
    ``cell_px`` pixels. Walls are ``wall_px`` thick and lie on the lattice lines
    (pixels ``[k * cell_px, k * cell_px + wall_px)`` along each axis), so the
    image is ``n * cell_px + wall_px`` pixels along each axis and every corridor
    is ``cell_px - wall_px`` pixels wide. The outer border is closed.

    Passages are carved by randomized depth-first search (the "recursive
    backtracker", written with an explicit stack): start at a random cell, move
    to a random unvisited neighbour knocking down the wall between, and back
    up when stuck. Each cell is entered once, through one knocked-down wall, so
    the passages form a spanning tree of the cell graph: the maze is perfect,
    every cell is reachable and there is exactly one path between two cells.
    (Depth-first mazes are not uniform over spanning trees; they favour long
    winding corridors, which suits a range sensor.)

    Parameters
    ----------
    n_cells_x, n_cells_y : int
        Maze cells along x (image columns) and y (image rows), each >= 1.
    cell_px : int
        Lattice pitch in pixels; must exceed ``wall_px``.
    wall_px : int
        Wall thickness in pixels, >= 1.
    rng : numpy.random.Generator
        Source of randomness; the same generator state gives the same maze.

    Returns
    -------
    numpy.ndarray of bool, shape (n_cells_y * cell_px + wall_px, n_cells_x * cell_px + wall_px)
        ``True`` on walls, in **image orientation** (row 0 is the top of the
        picture, as it will be saved). Flip it with ``numpy.flipud`` for the
        grid convention of :class:`robolab.maps.OccupancyGrid` (row 0 at the
        bottom).

    Raises
    ------
    TypeError
        A size is not an integer or ``rng`` is not a ``numpy.random.Generator``.
    ValueError
        A size is too small, or ``cell_px <= wall_px``.
    """
    nx = _check_int("n_cells_x", n_cells_x, 1)
    ny = _check_int("n_cells_y", n_cells_y, 1)
    pitch = _check_int("cell_px", cell_px, 2)
    wall = _check_int("wall_px", wall_px, 1)
    if pitch <= wall:
        raise ValueError(f"cell_px must be larger than wall_px ({wall}), got {pitch}")
    check_rng(rng)

    # open_east[r, c]: passage between maze cells (r, c) and (r, c + 1);
    # open_south[r, c]: between (r, c) and (r + 1, c).
    open_east = np.zeros((ny, nx), dtype=bool)
    open_south = np.zeros((ny, nx), dtype=bool)
    visited = np.zeros((ny, nx), dtype=bool)
    start = (int(rng.integers(ny)), int(rng.integers(nx)))
    visited[start] = True
    stack = [start]
    moves = ((0, 1), (1, 0), (0, -1), (-1, 0))
    while stack:  # a loop over maze cells: not a hot path (100 cells for the bundled maze)
        r, c = stack[-1]
        options = [
            (r + dr, c + dc)
            for dr, dc in moves
            if 0 <= r + dr < ny and 0 <= c + dc < nx and not visited[r + dr, c + dc]
        ]
        if not options:
            stack.pop()
            continue
        nr, nc = options[int(rng.integers(len(options)))]
        if nr == r:
            open_east[r, min(c, nc)] = True
        else:
            open_south[min(r, nr), c] = True
        visited[nr, nc] = True
        stack.append((nr, nc))

    h, w = ny * pitch + wall, nx * pitch + wall
    img = np.zeros((h, w), dtype=bool)
    for k in range(ny + 1):  # horizontal lattice lines
        img[k * pitch : k * pitch + wall, :] = True
    for k in range(nx + 1):  # vertical lattice lines
        img[:, k * pitch : k * pitch + wall] = True
    # Knock down walls: the gap spans the corridor width between the wall posts.
    for r, c in zip(*np.nonzero(open_east), strict=True):
        x0 = (c + 1) * pitch
        img[r * pitch + wall : (r + 1) * pitch, x0 : x0 + wall] = False
    for r, c in zip(*np.nonzero(open_south), strict=True):
        y0 = (r + 1) * pitch
        img[y0 : y0 + wall, c * pitch + wall : (c + 1) * pitch] = False
    return img


def write_maze(out_dir) -> Path:
    """Write the bundled maze as ``maze.png`` + ``maze.yaml`` into ``out_dir``.

    The image is drawn by :func:`generate_maze` from the fixed seed
    :data:`MAZE_SEED` (10 x 10 cells of 1 m, 0.15 m walls, 0.05 m per pixel),
    so the output is byte-for-byte reproducible. The PNG is 8-bit grey with
    walls black (0) and free space white (255), row 0 at the top as in any
    image; the YAML follows ROS map_server (``image``, ``resolution``,
    ``origin: [0, 0, 0]``, ``negate: 0``, ``occupied_thresh: 0.65``,
    ``free_thresh: 0.196``), so :func:`robolab.maps.load_maze` (or
    ``load_map(out_dir / "maze.yaml")``) reads it back in metres, and
    ``load_map(out_dir / "maze.png")`` in pixel units with the same occupancy.

    Parameters
    ----------
    out_dir : str or Path
        Folder to write to; created when missing.

    Returns
    -------
    Path
        The path of ``maze.yaml``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    walls = generate_maze(rng=np.random.default_rng(MAZE_SEED), **_BUNDLED)
    img = np.where(walls, 0, 255).astype(np.uint8)
    png = out / "maze.png"
    # No metadata chunks (time, software), so the file depends only on the pixels.
    Image.fromarray(img, mode="L").save(png, format="PNG", optimize=False)
    meta = {
        "image": png.name,
        "resolution": MAZE_RESOLUTION,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    yaml_path = out / "maze.yaml"
    yaml_path.write_text(yaml.safe_dump(meta, sort_keys=False))
    return yaml_path
