"""Occupancy grids: the map type, image and ROS map_server I/O, and cell <-> world conversion.

Storage convention: ``data[row, col]`` with ``row`` growing with y and ``col``
with x, so that ``data[0, 0]`` is the cell at the map origin (the lower-left
corner in a map_server file). Images store row 0 at the top; the loaders flip
them. Cell values are occupancy probabilities in [0, 1], or ``-1`` for unknown.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from PIL import Image, UnidentifiedImageError

from robolab.validation import as_array, check_positive

__all__ = [
    "OccupancyGrid",
    "MapFormatError",
    "UNKNOWN",
    "load_map",
    "save_map",
    "image_to_occupancy",
    "load_maze",
    "from_logodds",
]

#: Cell value for unknown space.
UNKNOWN = -1.0
#: Cell indices stay below this in magnitude (int64 with room for arithmetic on them).
_MAX_CELL_INDEX = 2.0**62

_IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".pgm", ".ppm", ".bmp", ".tif", ".tiff"}


class MapFormatError(ValueError):
    """A map file is missing, unreadable, or lacks what the format requires."""


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """A 2D occupancy grid.

    Parameters
    ----------
    data : array_like, shape (H, W)
        Occupancy in [0, 1] (1 = occupied) or -1 for unknown; ``data[row, col]``,
        row = y index, col = x index, row 0 at the origin.
    resolution : float
        Cell size in metres per cell.
    origin : (x, y, theta)
        World pose of the lower-left corner of cell ``(0, 0)``, as in map_server.
    occupied_threshold : float
        A cell with ``data >= occupied_threshold`` counts as an obstacle for ray
        casting and distance fields.

    Notes
    -----
    The grid keeps a read-only copy of ``data``; use :meth:`with_data` to make an
    updated map.
    """

    data: np.ndarray
    resolution: float
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    occupied_threshold: float = 0.5

    def __post_init__(self):
        data = as_array("data", self.data, ndim=2)
        if data.size == 0:
            raise ValueError("data must be a non-empty 2D array")
        known = data[data != UNKNOWN]
        if np.any(~np.isfinite(known)) or np.any((known < 0) | (known > 1)):
            raise ValueError(
                "data values must be occupancy probabilities in [0, 1] or -1 (unknown)"
            )
        origin = as_array("origin", self.origin, shape=(3,), finite=True)
        # A grid is immutable: caches keyed on it (ray casting, distance fields) stay
        # valid, and an update makes a new grid with `with_data`.
        data = np.array(data, dtype=float, copy=True)
        data.setflags(write=False)
        object.__setattr__(self, "data", data)
        object.__setattr__(self, "resolution", check_positive("resolution", self.resolution))
        object.__setattr__(self, "origin", origin)
        if not 0 < self.occupied_threshold <= 1:
            raise ValueError(f"occupied_threshold must be in (0, 1], got {self.occupied_threshold}")

    # -- shape ---------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` = ``(H, W)``."""
        return self.data.shape

    @property
    def width(self) -> float:
        """Extent along the map's x axis, metres."""
        return self.data.shape[1] * self.resolution

    @property
    def height(self) -> float:
        """Extent along the map's y axis, metres."""
        return self.data.shape[0] * self.resolution

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(left, right, bottom, top)`` in world metres, for ``imshow(..., origin='lower')``.

        Only meaningful when the origin's yaw is 0.
        """
        x0, y0 = (float(v) for v in self.origin[:2])  # plain floats: they print as numbers
        return (x0, x0 + float(self.width), y0, y0 + float(self.height))

    @property
    def occupied(self) -> np.ndarray:
        """Boolean mask of obstacle cells (``data >= occupied_threshold``)."""
        return self.data >= self.occupied_threshold

    @property
    def free(self) -> np.ndarray:
        """Boolean mask of known free cells (``0 <= data < occupied_threshold``)."""
        return (self.data >= 0) & (self.data < self.occupied_threshold)

    @property
    def unknown(self) -> np.ndarray:
        """Boolean mask of unknown cells."""
        return self.data == UNKNOWN

    # -- conversion: the one place that maps between cells and metres ------------------
    def world_to_map(self, xy) -> np.ndarray:
        """Map coordinates in cells, ``(..., 2)`` as (col, row), of world points ``(..., 2)``."""
        p = np.asarray(xy, dtype=float)
        d = p - self.origin[:2]
        c, s = np.cos(self.origin[2]), np.sin(self.origin[2])
        with np.errstate(invalid="ignore"):  # inf * 0 is NaN: such a point has no cell
            u = (c * d[..., 0] + s * d[..., 1]) / self.resolution
            v = (-s * d[..., 0] + c * d[..., 1]) / self.resolution
        return np.stack([u, v], -1)

    def world_to_cell(self, xy) -> np.ndarray:
        """Integer cell indices ``(..., 2)`` as ``(row, col)`` of world points ``(..., 2)``.

        Indices may lie outside the grid; use :meth:`contains_cell` to test (or
        :meth:`contains`, which also takes points that have no cell).

        Raises
        ------
        ValueError
            When a point is NaN or infinite, or so far away (beyond ``2**62`` cells)
            that its index is no integer: it has no cell, and a cast would give a
            meaningless ``-9223372036854775808``.
        """
        uv = np.floor(self.world_to_map(xy))
        bad = ~(np.abs(uv) < _MAX_CELL_INDEX).all(-1)  # NaN compares False: caught too
        if bad.any():
            i = int(np.flatnonzero(bad.reshape(-1))[0])
            point = tuple(float(v) for v in np.asarray(xy, dtype=float).reshape(-1, 2)[i])
            raise ValueError(
                f"xy: world point {point} (point {i}) has no cell: coordinates must be "
                f"finite and within {_MAX_CELL_INDEX:.3g} cells of the map origin"
            )
        uv = uv.astype(np.int64)
        return np.stack([uv[..., 1], uv[..., 0]], -1)

    def cell_to_world(self, cells) -> np.ndarray:
        """World coordinates ``(..., 2)`` of the centres of cells given as ``(row, col)``."""
        rc = np.asarray(cells, dtype=float)
        u = (rc[..., 1] + 0.5) * self.resolution
        v = (rc[..., 0] + 0.5) * self.resolution
        c, s = np.cos(self.origin[2]), np.sin(self.origin[2])
        return np.stack([self.origin[0] + c * u - s * v, self.origin[1] + s * u + c * v], -1)

    def contains_cell(self, cells) -> np.ndarray:
        """Boolean mask: which ``(row, col)`` indices lie inside the grid."""
        rc = np.asarray(cells)
        return (
            (rc[..., 0] >= 0)
            & (rc[..., 0] < self.shape[0])
            & (rc[..., 1] >= 0)
            & (rc[..., 1] < self.shape[1])
        )

    def contains(self, xy) -> np.ndarray:
        """Boolean mask: which world points lie inside the grid (NaN and inf do not)."""
        uv = np.floor(self.world_to_map(xy))  # compared as floats: NaN is never inside
        return (
            (uv[..., 1] >= 0)
            & (uv[..., 1] < self.shape[0])
            & (uv[..., 0] >= 0)
            & (uv[..., 0] < self.shape[1])
        )

    def cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """World x and y of every cell centre, each of shape ``(H, W)``."""
        rows, cols = np.indices(self.shape)
        xy = self.cell_to_world(np.stack([rows, cols], -1))
        return xy[..., 0], xy[..., 1]

    def with_data(self, data) -> OccupancyGrid:
        """A grid with the same geometry and new cell values."""
        return OccupancyGrid(data, self.resolution, self.origin.copy(), self.occupied_threshold)


def from_logodds(logodds, grid: OccupancyGrid, *, prior: float = 0.0, observed=None):
    r"""The occupancy grid of a log-odds map, with never-observed cells **unknown**.

    A cell's probability is :math:`p = 1 - 1 / (1 + e^{l})`, except where the cell
    was never observed: there it is :data:`UNKNOWN` (-1), as map_server's -1.
    Unknown is neither free nor occupied (:attr:`OccupancyGrid.occupied` and
    :attr:`OccupancyGrid.free` are both False there): ray casting passes through
    it and the likelihood field measures distances to occupied cells only.

    Without this, ``grid.with_data(logodds_to_probability(l))`` turns every unseen
    cell (log-odds = prior = 0, p = 0.5) into an obstacle, since a cell counts as
    occupied at ``p >= occupied_threshold`` (0.5): rays cast from inside such a map
    stop at once.

    Parameters
    ----------
    logodds : array_like, shape grid.shape
        Log-odds; ``+-inf`` allowed (p = 1 / 0), NaN not.
    grid : OccupancyGrid
        The geometry (resolution, origin, threshold) of the result.
    prior : float
        The prior log-odds :math:`l_0` the map started from.
    observed : array_like of bool, shape grid.shape, optional
        Which cells any beam updated (e.g. accumulate ``new != old`` per scan).
        Default: the cells whose log-odds differ from ``prior``.

    Returns
    -------
    OccupancyGrid
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    lo = as_array("logodds", logodds, shape=grid.shape)
    if np.any(np.isnan(lo)):
        raise ValueError("logodds must not contain NaN")
    l0 = float(prior)
    if not np.isfinite(l0):
        raise ValueError(f"prior must be finite, got {prior!r}")
    if observed is None:
        seen = lo != l0
    else:
        seen = np.asarray(observed)
        if seen.dtype != bool or seen.shape != grid.shape:
            raise ValueError(
                f"observed must be a bool array of shape {grid.shape}, "
                f"got {seen.dtype} {seen.shape}"
            )
    from scipy.special import expit  # here: scipy.special costs 0.1 s to import

    return grid.with_data(np.where(seen, expit(lo), UNKNOWN))


def image_to_occupancy(image: np.ndarray, level: float = 0.5) -> np.ndarray:
    """Binary occupancy from an image, like MATLAB's ``1 - im2bw(A, level)``.

    Luminance (ITU-R BT.601 weights, as MATLAB's rgb2gray) above ``level`` is free
    (0), the rest occupied (1). Returns rows in image order (row 0 at the top).
    """
    img = np.asarray(image)
    if img.ndim == 3:
        img = img[..., :3].astype(float) @ np.array([0.2989, 0.5870, 0.1140])
    scale = 65535.0 if np.asarray(image).dtype == np.uint16 else 255.0
    lum = img.astype(float) / scale
    return (lum <= level).astype(float)


#: Pillow modes of 16-bit grey images (PNG gives ``I;16``, PGM with maxval > 255 gives ``I``).
_SIXTEEN_BIT_MODES = ("I;16", "I;16B", "I;16L", "I;16N", "I")


def _read_image(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Pixels of an image file and its alpha channel.

    Returns
    -------
    pixels : numpy.ndarray
        ``(H, W)`` grey or ``(H, W, 3)`` RGB, ``uint8`` or (16-bit images) ``uint16``.
    alpha : numpy.ndarray or None
        ``(H, W)`` opacity in [0, 1] when the image has an alpha channel (RGBA, LA,
        or a palette with transparency), else None.
    """
    if not path.is_file():
        state = "is a folder, not an image" if path.is_dir() else "does not exist"
        raise MapFormatError(f"map image {str(path)!r} {state}")
    try:
        with Image.open(path) as im:
            if im.mode in ("P", "PA"):
                im = im.convert("RGBA" if im.mode == "PA" or "transparency" in im.info else "RGB")
            elif im.mode == "1":
                im = im.convert("L")
            elif im.mode not in ("L", "LA", "RGB", "RGBA", *_SIXTEEN_BIT_MODES):
                im = im.convert("RGB")
            im.load()
            arr = np.array(im)
    except Image.DecompressionBombError as exc:
        raise MapFormatError(
            f"map image {str(path)!r} is too large to load: its header claims more pixels "
            f"than Pillow's limit of {Image.MAX_IMAGE_PIXELS} ({exc})"
        ) from exc
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as exc:
        raise MapFormatError(f"map image {str(path)!r} is not a readable image: {exc}") from exc
    if arr.dtype not in (np.uint8, np.uint16):  # 32-bit "I": 16-bit PGM, or a wider TIFF
        if arr.size and (arr.min() < 0 or arr.max() > 65535):
            raise MapFormatError(
                f"map image {str(path)!r}: pixel values outside 0..65535 (mode {im.mode}); "
                f"only 8- and 16-bit images are maps"
            )
        arr = arr.astype(np.uint16)
    if arr.ndim == 3 and arr.shape[-1] in (2, 4):  # LA, RGBA: split off the alpha channel
        alpha = arr[..., -1].astype(float) / np.iinfo(arr.dtype).max
        arr = arr[..., 0] if arr.shape[-1] == 2 else arr[..., :3]
        return arr, alpha
    return arr, None


def load_map(
    path, *, resolution: float = 1.0, origin=(0.0, 0.0, 0.0), level: float = 0.5
) -> OccupancyGrid:
    """Load an occupancy grid from an image or a ROS map_server YAML file.

    Parameters
    ----------
    path : str or Path
        A ``.yaml``/``.yml`` map_server description, or an image (PNG, JPG, PGM
        P5 grey or P6 RGB, ...).
    resolution, origin : optional
        For a bare image only: metres per pixel (default 1, pixel units as in
        the measurement-model lab) and the origin pose.
    level : float
        For a bare image only: luminance threshold, as MATLAB's ``im2bw(A, level)``.

    Returns
    -------
    OccupancyGrid
        Row 0 of the result is the bottom row of the image.

    Raises
    ------
    MapFormatError
        Missing or unreadable file, YAML without the required keys, bad values.
    """
    path = Path(path)
    if path.suffix.lower() in (".yaml", ".yml"):
        return _load_map_server(path)
    if not path.exists():
        raise MapFormatError(f"map file {str(path)!r} does not exist")
    if path.suffix.lower() not in _IMAGE_SUFFIXES:
        raise MapFormatError(
            f"{str(path)!r}: unknown map format {path.suffix!r}; expected .yaml or an image"
        )
    occ = image_to_occupancy(_read_image(path)[0], level)
    return OccupancyGrid(np.flipud(occ), resolution, np.asarray(origin, dtype=float))


def _load_map_server(path: Path) -> OccupancyGrid:
    if not path.is_file():
        state = "is a folder, not a YAML file" if path.is_dir() else "does not exist"
        raise MapFormatError(f"map file {str(path)!r} {state}")
    try:
        meta = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise MapFormatError(f"map file {str(path)!r} is not valid YAML: {exc}") from exc
    if not isinstance(meta, dict):
        raise MapFormatError(
            f"map file {str(path)!r} must be a YAML mapping with image, resolution and origin"
        )
    missing = [k for k in ("image", "resolution", "origin") if k not in meta]
    if missing:
        raise MapFormatError(f"map file {str(path)!r} lacks required key(s): {', '.join(missing)}")
    try:
        resolution = float(meta["resolution"])
        origin = np.asarray(meta["origin"], dtype=float)
        negate = int(meta.get("negate", 0))
        occ_th = float(meta.get("occupied_thresh", 0.65))
        free_th = float(meta.get("free_thresh", 0.196))
    except (TypeError, ValueError) as exc:
        raise MapFormatError(f"map file {str(path)!r} has a non-numeric value: {exc}") from exc
    if not np.isfinite(resolution) or not np.all(np.isfinite(origin)):
        raise MapFormatError(
            f"map file {str(path)!r}: resolution and origin must be finite numbers"
        )
    if origin.shape != (3,):
        raise MapFormatError(
            f"map file {str(path)!r}: origin must be [x, y, yaw], got {meta['origin']!r}"
        )
    if resolution <= 0:
        raise MapFormatError(f"map file {str(path)!r}: resolution must be > 0, got {resolution}")
    if not 0 <= free_th < occ_th <= 1:
        raise MapFormatError(
            f"map file {str(path)!r}: need 0 <= free_thresh < occupied_thresh <= 1"
        )
    mode = str(meta.get("mode", "trinary"))
    if mode not in ("trinary", "scale"):
        raise MapFormatError(
            f"map file {str(path)!r}: mode {mode!r} not supported (trinary or scale)"
        )
    image_path = Path(meta["image"])
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    raw, alpha = _read_image(image_path)
    # map_server reads the grey level x in [0, 1] (x / 255 for 8 bits, x / 65535 for 16),
    # averaging the colour channels of an RGB image.
    img = raw.astype(float) / np.iinfo(raw.dtype).max
    if img.ndim == 3:
        img = img.mean(axis=-1)
    # map_server: p = 1 - x is the occupancy probability unless negated.
    p = img if negate else 1.0 - img
    data = np.full(p.shape, UNKNOWN)
    data[p > occ_th] = 1.0
    data[p < free_th] = 0.0
    if mode == "scale":
        between = (p >= free_th) & (p <= occ_th)
        data[between] = (p[between] - free_th) / (occ_th - free_th)
        if alpha is not None:  # map_server: in scale mode any transparency means unknown
            data[alpha < 1.0] = UNKNOWN
    return OccupancyGrid(np.flipud(data), resolution, origin)


def _maps_using(image_path: Path, except_yaml: Path) -> list[Path]:
    """map_server YAML files next to ``image_path`` whose ``image`` is that file."""
    users = []
    for other in sorted(image_path.parent.glob("*.y*ml")):
        if other.suffix.lower() not in (".yaml", ".yml") or other.resolve() == except_yaml:
            continue
        try:
            meta = yaml.safe_load(other.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, yaml.YAMLError):
            continue  # not a map file
        if isinstance(meta, dict) and isinstance(meta.get("image"), str):
            target = Path(meta["image"])
            if not target.is_absolute():
                target = other.parent / target
            if target.resolve() == image_path.resolve():
                users.append(other)
    return users


def save_map(
    grid: OccupancyGrid,
    yaml_path,
    *,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
    image=None,
) -> Path:
    """Write ``grid`` as map_server YAML + binary PGM (P5), like ``map_saver``.

    Occupied cells (``>= occupied_thresh``) become 0, free cells (``<= free_thresh``)
    254 and the rest (unknown or in between) 205. Returns the YAML path.

    Parameters
    ----------
    grid : OccupancyGrid
    yaml_path : str or Path
        The ``.yaml`` / ``.yml`` file to write.
    occupied_thresh, free_thresh : float
        Written to the YAML and used to pick the pixel values.
    image : str or Path, optional
        The image file, relative to the YAML's folder; default the YAML's name with
        ``.pgm`` (``x.yaml`` and ``x.yml`` both give ``x.pgm``).

    Raises
    ------
    FileExistsError
        The image file is the image of *another* map_server YAML in its folder
        (e.g. ``save_map(grid, "x.yml")`` next to an ``x.yaml`` that uses
        ``x.pgm``): overwriting it would silently change that map. Pass ``image=``.
    """
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    yaml_path = Path(yaml_path)
    if yaml_path.suffix.lower() not in (".yaml", ".yml"):
        raise ValueError(f"yaml_path must end in .yaml or .yml, got {str(yaml_path)!r}")
    pgm_path = yaml_path.with_suffix(".pgm") if image is None else yaml_path.parent / image
    if pgm_path.exists():
        users = _maps_using(pgm_path, yaml_path.resolve())
        if users:
            raise FileExistsError(
                f"{str(pgm_path)!r} is the image of {', '.join(map(str, users))}: "
                f"saving {str(yaml_path)!r} would overwrite it; pass image= another file name"
            )
    d = grid.data
    img = np.full(d.shape, 205, dtype=np.uint8)
    img[(d >= 0) & (d <= free_thresh)] = 254
    img[d >= occupied_thresh] = 0
    yaml_path.parent.mkdir(parents=True, exist_ok=True)
    pgm_path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.flipud(img), mode="L").save(pgm_path)
    meta = {
        "image": pgm_path.name if image is None else Path(image).as_posix(),
        "resolution": float(grid.resolution),
        "origin": [float(v) for v in grid.origin],
        "negate": 0,
        "occupied_thresh": occupied_thresh,
        "free_thresh": free_thresh,
    }
    yaml_path.write_text(yaml.safe_dump(meta, sort_keys=False))
    return yaml_path


def load_maze() -> OccupancyGrid:
    """The bundled maze of the measurement-model lab (``data/maze.yaml`` + ``data/maze.png``)."""
    from robolab import DATA_DIR

    path = DATA_DIR / "maze.yaml"
    if not path.is_file():
        raise MapFormatError(
            f"the bundled maze {str(path)!r} is missing; run `robolab data` to make it"
        )
    return load_map(path)
