"""robolab.maps: OccupancyGrid, cell <-> world conversion, image and map_server I/O."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from robolab.maps import (
    UNKNOWN,
    MapFormatError,
    OccupancyGrid,
    image_to_occupancy,
    load_map,
    save_map,
)

OLIN_YAML = (
    Path(__file__).resolve().parents[2] / "shared" / "data" / "olin_ac109_1" / "ac109_1.yaml"
)


# -- OccupancyGrid validation ---------------------------------------------------------------------
def test_grid_stores_float_data_and_geometry():
    g = OccupancyGrid(np.array([[0, 1, 1], [0, 0, 1]]), 0.05, (1.0, -2.0, 0.0))
    assert g.data.dtype == np.float64 and g.shape == (2, 3)
    assert g.resolution == 0.05 and isinstance(g.resolution, float)
    np.testing.assert_array_equal(g.origin, [1.0, -2.0, 0.0])
    assert g.width == pytest.approx(0.15) and g.height == pytest.approx(0.10)
    assert g.extent == pytest.approx((1.0, 1.15, -2.0, -1.9))


def test_grid_masks():
    g = OccupancyGrid(np.array([[0.0, 0.49, 0.5, 1.0, -1.0]]), 1.0)
    np.testing.assert_array_equal(g.occupied, [[False, False, True, True, False]])
    np.testing.assert_array_equal(g.free, [[True, True, False, False, False]])
    np.testing.assert_array_equal(g.unknown, [[False, False, False, False, True]])


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"data": np.zeros(5)}, ValueError, r"data must have 2 dimension"),
        ({"data": np.zeros((0, 3))}, ValueError, r"data must be a non-empty"),
        ({"data": [[0.0, 1.5]]}, ValueError, r"data values must be occupancy probabilities"),
        ({"data": [[0.0, -0.5]]}, ValueError, r"data values must be"),
        ({"data": [[0.0, np.nan]]}, ValueError, r"data values must be"),
        ({"data": [["a", "b"]]}, TypeError, r"data must be numeric"),
        ({"resolution": 0.0}, ValueError, r"resolution must be > 0"),
        ({"resolution": -0.1}, ValueError, r"resolution must be > 0"),
        ({"resolution": "fine"}, TypeError, r"resolution must be a number"),
        ({"origin": (0.0, 0.0)}, ValueError, r"origin must have shape \(3,\)"),
        ({"origin": (0.0, np.inf, 0.0)}, ValueError, r"origin must be finite"),
        ({"occupied_threshold": 0.0}, ValueError, r"occupied_threshold must be in \(0, 1\]"),
        ({"occupied_threshold": 1.5}, ValueError, r"occupied_threshold"),
    ],
)
def test_grid_validation_errors(kwargs, exc, match):
    args = {"data": np.zeros((2, 2)), "resolution": 1.0, "origin": (0.0, 0.0, 0.0)} | kwargs
    with pytest.raises(exc, match=match):
        OccupancyGrid(**args)


def test_with_data_keeps_geometry():
    g = OccupancyGrid(np.zeros((3, 4)), 0.1, (1.0, 2.0, 0.3), occupied_threshold=0.7)
    h = g.with_data(np.ones((3, 4)))
    assert h.resolution == g.resolution and h.occupied_threshold == 0.7
    np.testing.assert_array_equal(h.origin, g.origin)
    assert h.origin is not g.origin
    assert h.occupied.all()


# -- cell <-> world -------------------------------------------------------------------------------
def test_world_to_cell_hand_computed():
    g = OccupancyGrid(np.zeros((10, 20)), 0.5, (-1.0, 2.0, 0.0))
    # x = 0.3 -> (0.3 + 1) / 0.5 = 2.6 -> col 2; y = 4.9 -> (4.9 - 2) / 0.5 = 5.8 -> row 5
    np.testing.assert_array_equal(g.world_to_cell([0.3, 4.9]), [5, 2])
    np.testing.assert_allclose(g.world_to_map([0.3, 4.9]), [2.6, 5.8])
    # the origin corner belongs to cell (0, 0); just below / left of it is outside
    np.testing.assert_array_equal(g.world_to_cell([-1.0, 2.0]), [0, 0])
    np.testing.assert_array_equal(g.world_to_cell([-1.0 - 1e-9, 2.0 - 1e-9]), [-1, -1])
    np.testing.assert_allclose(g.cell_to_world([5, 2]), [0.25, 4.75])


@pytest.mark.parametrize("origin", [(-3.7, 12.1, 0.0), (2.0, -1.0, 0.6), (0.5, 0.5, -2.5)])
@pytest.mark.parametrize("resolution", [0.05, 0.37, 2.0])
def test_cell_world_round_trip(origin, resolution):
    g = OccupancyGrid(np.zeros((30, 40)), resolution, origin)
    rows, cols = np.indices(g.shape)
    cells = np.stack([rows, cols], -1)  # (30, 40, 2)
    np.testing.assert_array_equal(g.world_to_cell(g.cell_to_world(cells)), cells)
    # any point of a cell maps back to it: offsets within (-0.5, 0.5) cell around the centre
    rng = np.random.default_rng(0)
    off = rng.uniform(-0.49, 0.49, size=cells.shape)
    np.testing.assert_array_equal(g.world_to_cell(g.cell_to_world(cells + off)), cells)
    assert g.contains_cell(cells).all()


def test_rotated_origin_by_hand():
    # Map x axis along world +y: cell (row 0, col 2) centre is 2.5 cells along world +y.
    g = OccupancyGrid(np.zeros((4, 5)), 2.0, (10.0, 20.0, np.pi / 2))
    np.testing.assert_allclose(g.cell_to_world([0, 2]), [10.0 - 1.0, 20.0 + 5.0], atol=1e-12)
    np.testing.assert_array_equal(g.world_to_cell([9.0, 25.0]), [0, 2])
    np.testing.assert_array_equal(
        g.world_to_cell([6.5, 20.5]), [1, 0]
    )  # 3.5 m along world -x = map +y


def test_contains_and_cell_centers():
    g = OccupancyGrid(np.zeros((2, 3)), 1.0, (0.0, 0.0, 0.0))
    np.testing.assert_array_equal(
        g.contains([[0.5, 0.5], [2.9, 1.9], [3.0, 0.5], [-0.1, 0.5]]), [True, True, False, False]
    )
    x, y = g.cell_centers()
    np.testing.assert_allclose(x, [[0.5, 1.5, 2.5]] * 2)
    np.testing.assert_allclose(y, [[0.5] * 3, [1.5] * 3])


# -- images ---------------------------------------------------------------------------------------
def _pattern():
    """A 4 x 6 grey image: top-left black block, rest white; row 0 is the top of the image."""
    img = np.full((4, 6), 255, dtype=np.uint8)
    img[0, 0:2] = 0
    img[1, 0] = 127  # just below im2bw's 0.5 -> occupied
    img[1, 1] = 128  # just above -> free
    return img


def _expected_occ():
    occ = np.zeros((4, 6))
    occ[0, 0:2] = 1.0
    occ[1, 0] = 1.0
    return np.flipud(occ)  # loaders put image row 0 at the top of the map (last row)


@pytest.mark.parametrize("suffix", [".png", ".pgm"])
def test_load_grey_image_lossless(tmp_path, suffix):
    path = tmp_path / f"map{suffix}"
    Image.fromarray(_pattern()).save(path)
    if suffix == ".pgm":
        assert path.read_bytes()[:2] == b"P5"
    g = load_map(path, resolution=0.1, origin=(1.0, 2.0, 0.0))
    np.testing.assert_array_equal(g.data, _expected_occ())
    assert g.resolution == 0.1
    np.testing.assert_array_equal(g.origin, [1.0, 2.0, 0.0])


def test_load_ppm_p6_rgb(tmp_path):
    rgb = np.stack([_pattern()] * 3, -1)
    path = tmp_path / "map.ppm"
    Image.fromarray(rgb).save(path)
    assert path.read_bytes()[:2] == b"P6"
    np.testing.assert_array_equal(load_map(path).data, _expected_occ())


def test_load_jpg_blocks(tmp_path):
    img = np.full((32, 48), 255, dtype=np.uint8)
    img[8:24, 8:24] = 0  # 8-aligned blocks survive JPEG closely
    path = tmp_path / "map.jpg"
    Image.fromarray(img).save(path, quality=95)
    occ = load_map(path).data
    np.testing.assert_array_equal(occ, np.flipud(img == 0).astype(float))


def test_rgb_threshold_like_matlab_im2bw():
    # MATLAB: im2bw(A, 0.5) on RGB = rgb2gray (0.2989 R + 0.5870 G + 0.1140 B) > 0.5 -> white.
    rgb = np.array(
        [[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0], [200, 200, 200], [128, 128, 128]]],
        dtype=np.uint8,
    )
    # luminances: 0.299, 0.587, 0.114, 0.886, 0.784, 0.502 -> occupied where <= 0.5
    np.testing.assert_array_equal(image_to_occupancy(rgb, 0.5), [[1.0, 0.0, 1.0, 0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(image_to_occupancy(rgb, 0.6), [[1.0, 1.0, 1.0, 0.0, 0.0, 1.0]])


def test_rgb_png_with_alpha_and_16_bit_grey(tmp_path):
    rgba = np.zeros((2, 2, 4), dtype=np.uint8)
    rgba[..., 3] = 255
    rgba[0, 1, :3] = 255
    Image.fromarray(rgba).save(tmp_path / "a.png")
    np.testing.assert_array_equal(load_map(tmp_path / "a.png").data, [[1.0, 1.0], [1.0, 0.0]])
    grey16 = np.array([[0, 65535], [30000, 40000]], dtype=np.uint16)
    Image.fromarray(grey16).save(tmp_path / "b.png")
    np.testing.assert_array_equal(load_map(tmp_path / "b.png").data, [[1.0, 0.0], [1.0, 0.0]])


# -- map_server YAML ------------------------------------------------------------------------------
def _write_map_server(tmp_path, values, **meta):
    """Write a grey PGM of ``values`` (row 0 = image top) and a YAML beside it; return the YAML."""
    img_dir = tmp_path / "images"
    img_dir.mkdir(exist_ok=True)
    Image.fromarray(np.asarray(values, dtype=np.uint8)).save(img_dir / "room.pgm")
    doc = {"image": "images/room.pgm", "resolution": 0.05, "origin": [-1.5, 2.0, 0.0]} | meta
    path = tmp_path / "room.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


# grey 0 -> p = 1 (occupied), 254 -> p = 0.004 (free), 205 -> p = 0.196 (unknown),
# 100 -> p = 0.608 (between the default thresholds: unknown in trinary mode)
VALUES = [[0, 254], [205, 100]]


def test_map_server_trinary_with_relative_image_path(tmp_path):
    g = load_map(_write_map_server(tmp_path, VALUES))
    np.testing.assert_array_equal(g.data, np.flipud([[1.0, 0.0], [UNKNOWN, UNKNOWN]]))
    assert g.resolution == 0.05
    np.testing.assert_array_equal(g.origin, [-1.5, 2.0, 0.0])


def test_map_server_negate_and_thresholds(tmp_path):
    # negate: p = x / 255: 0 -> free, 254 -> occupied, 205 (0.80) -> occupied, 100 (0.39) -> unknown
    g = load_map(_write_map_server(tmp_path, VALUES, negate=1))
    np.testing.assert_array_equal(g.data, np.flipud([[0.0, 1.0], [1.0, UNKNOWN]]))
    # occupied_thresh 0.5 makes 100 (p = 0.608) occupied; free_thresh 0.25 makes 205 free
    g = load_map(_write_map_server(tmp_path, VALUES, occupied_thresh=0.5, free_thresh=0.25))
    np.testing.assert_array_equal(g.data, np.flipud([[1.0, 0.0], [0.0, 1.0]]))


def test_map_server_scale_mode(tmp_path):
    g = load_map(
        _write_map_server(tmp_path, VALUES, mode="scale", occupied_thresh=0.65, free_thresh=0.196)
    )
    p = (255 - 100) / 255
    between = (p - 0.196) / (0.65 - 0.196)
    np.testing.assert_allclose(
        g.data, np.flipud([[1.0, 0.0], [(50 / 255 - 0.196) / (0.65 - 0.196), between]])
    )


def test_map_server_absolute_image_path_and_rgb_average(tmp_path):
    rgb = np.zeros((1, 2, 3), dtype=np.uint8)
    rgb[0, 1] = [254, 254, 254]
    rgb[0, 0] = [0, 0, 60]  # mean 20 -> p = 0.92 -> occupied
    img = tmp_path / "colour.ppm"
    Image.fromarray(rgb).save(img)
    path = tmp_path / "abs.yaml"
    path.write_text(yaml.safe_dump({"image": str(img), "resolution": 1.0, "origin": [0, 0, 0]}))
    np.testing.assert_array_equal(load_map(path).data, [[1.0, 0.0]])


def test_save_map_round_trip(tmp_path):
    data = np.full((5, 7), UNKNOWN)
    data[1:4, 1:6] = 0.0
    data[2, 3] = 1.0
    data[0, 0] = 1.0
    g = OccupancyGrid(data, 0.025, (-3.25, 1.5, 0.125))
    out = save_map(g, tmp_path / "sub" / "saved.yaml")
    assert out == tmp_path / "sub" / "saved.yaml"
    assert (tmp_path / "sub" / "saved.pgm").read_bytes()[:2] == b"P5"
    back = load_map(out)
    np.testing.assert_array_equal(back.data, data)
    assert back.resolution == 0.025
    np.testing.assert_array_equal(back.origin, g.origin)


def test_save_map_bad_arguments(tmp_path):
    with pytest.raises(TypeError, match="grid must be an OccupancyGrid"):
        save_map(np.zeros((2, 2)), tmp_path / "m.yaml")
    with pytest.raises(ValueError, match="yaml_path must end in .yaml"):
        save_map(OccupancyGrid(np.zeros((2, 2)), 1.0), tmp_path / "m.png")


# -- bad files: each a MapFormatError naming the file ---------------------------------------------
def _raises_naming(path, match=None):
    with pytest.raises(MapFormatError, match=match) as info:
        load_map(path)
    assert str(path) in str(info.value)
    assert isinstance(info.value, ValueError)


def test_missing_files(tmp_path):
    _raises_naming(tmp_path / "nope.png", "does not exist")
    _raises_naming(tmp_path / "nope.yaml", "does not exist")
    path = tmp_path / "lost.yaml"
    path.write_text(yaml.safe_dump({"image": "lost.pgm", "resolution": 0.1, "origin": [0, 0, 0]}))
    with pytest.raises(MapFormatError, match="does not exist") as info:
        load_map(path)
    assert "lost.pgm" in str(info.value)


def test_unknown_suffix(tmp_path):
    path = tmp_path / "map.txt"
    path.write_text("hello")
    _raises_naming(path, "unknown map format")


@pytest.mark.parametrize("name", ["corrupt.png", "corrupt.pgm", "corrupt.jpg"])
def test_corrupt_image_bytes(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(b"\x89PNG\r\n\x1a\n garbage that is not an image")
    _raises_naming(path, "not a readable image")


def test_truncated_image(tmp_path):
    path = tmp_path / "cut.png"
    Image.fromarray(np.zeros((64, 64), dtype=np.uint8)).save(path)
    path.write_bytes(path.read_bytes()[:60])
    _raises_naming(path, "not a readable image")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("- just\n- a list\n", "must be a YAML mapping"),
        ("42\n", "must be a YAML mapping"),
        ("", "must be a YAML mapping"),
        ("image: [unclosed\n", "not valid YAML"),
        ("image: m.pgm\nresolution: 0.1\n", "lacks required key.*origin"),
        ("resolution: 0.1\n", "lacks required key.*image.*origin"),
        ("image: m.pgm\nresolution: fine\norigin: [0, 0, 0]\n", "non-numeric"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0]\n", "origin must be"),
        ("image: m.pgm\nresolution: 0.1\norigin: [a, b, c]\n", "non-numeric"),
        ("image: m.pgm\nresolution: 0.1\norigin: 3\n", "origin must be"),
        ("image: m.pgm\nresolution: -0.1\norigin: [0, 0, 0]\n", "resolution must be > 0"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: maybe\n", "non-numeric"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 0.9\n", "free_thresh"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: raw\n", "mode"),
    ],
)
def test_bad_yaml(tmp_path, text, match):
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8)).save(tmp_path / "m.pgm")
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    _raises_naming(path, match)


@pytest.mark.parametrize(
    "text",
    [
        "image: m.pgm\nresolution: 0.1\norigin: [0, null, 0]\n",
        "image: m.pgm\nresolution: 0.1\norigin: [0, .inf, 0]\n",
        "image: m.pgm\nresolution: .nan\norigin: [0, 0, 0]\n",
        "image: m.pgm\nresolution: .inf\norigin: [0, 0, 0]\n",
    ],
)
def test_non_finite_yaml_values_are_map_format_errors(tmp_path, text):
    # float(None) would raise, but np.asarray([0, None, 0], float) silently makes NaN, and
    # .nan/.inf pass the `resolution <= 0` test: the grid's own ValueError then names no file.
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8)).save(tmp_path / "m.pgm")
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    _raises_naming(path)


def test_binary_yaml_is_map_format_error(tmp_path):
    # A .yaml that is really binary (e.g. an image saved under the wrong name) must not leak
    # a UnicodeDecodeError that does not name the file.
    path = tmp_path / "binary.yaml"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00\x01")
    _raises_naming(path)


# -- real data ------------------------------------------------------------------------------------
@pytest.mark.skipif(not OLIN_YAML.is_file(), reason="../shared/data/olin_ac109_1 is not available")
def test_real_olin_map_loads():
    image = OLIN_YAML.with_name("ac109_1.pgm")
    assert image.read_bytes()[:2] == b"P6"  # an RGB PPM despite the .pgm name
    meta = yaml.safe_load(OLIN_YAML.read_text())
    g = load_map(OLIN_YAML)
    assert g.resolution == 0.02
    np.testing.assert_array_equal(g.origin, np.asarray(meta["origin"], dtype=float))
    with Image.open(image) as im:
        w, h = im.size
    assert g.shape == (h, w)
    # a real room: walls, free floor and unknown outside, nothing else in trinary mode
    assert set(np.unique(g.data)) <= {UNKNOWN, 0.0, 1.0}
    assert g.occupied.sum() > 1000 and g.free.sum() > 10_000 and g.unknown.any()


# -- points with no cell (issue 25) ------------------------------------------------------------


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 1e30, -1e30])
def test_world_to_cell_refuses_points_without_a_cell_and_contains_says_outside(bad):
    # The int64 cast gave -9223372036854775808 for all of these.
    grid = OccupancyGrid(np.zeros((4, 5)), 0.5, (1.0, -2.0, 0.3))
    points = np.array([[1.2, -1.9], [bad, 0.0], [0.0, bad]])
    with pytest.raises(ValueError, match=r"xy: world point .* \(point 1\) has no cell"):
        grid.world_to_cell(points)
    with pytest.raises(ValueError, match="has no cell"):
        grid.world_to_cell(points[2])
    np.testing.assert_array_equal(grid.contains(points), [True, False, False])
    # Finite points far outside still get their (outside) index, as before.
    far = grid.world_to_cell([[1e6, 1e6]])
    assert not grid.contains_cell(far).any() and far.dtype == np.int64


def test_contains_agrees_with_world_to_cell_on_finite_points():
    rng = np.random.default_rng(3)
    grid = OccupancyGrid(np.zeros((6, 7)), 0.25, (-0.5, 0.25, 0.7))
    points = rng.uniform(-3, 3, size=(2000, 2))
    np.testing.assert_array_equal(
        grid.contains(points), grid.contains_cell(grid.world_to_cell(points))
    )


def test_load_map_names_a_folder_and_a_missing_file(tmp_path):
    (tmp_path / "map.png").mkdir()
    with pytest.raises(MapFormatError, match="is a folder"):
        load_map(tmp_path / "map.png")
    with pytest.raises(MapFormatError, match="does not exist"):
        load_map(tmp_path / "nothing")
    (tmp_path / "map.yaml").mkdir()
    with pytest.raises(MapFormatError, match="is a folder"):
        load_map(tmp_path / "map.yaml")
