"""Map files as map_server writes and reads them: bit depths, transparency, collisions, bombs.

The oracle is map_server's rule: a pixel's grey level ``x`` in [0, 1] (divided by
255 or 65535) gives ``p = 1 - x`` (``x`` if negated); ``p > occupied_thresh`` is
occupied, ``p < free_thresh`` free, the rest unknown in trinary mode and scaled in
scale mode, where any transparency means unknown.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from robolab.maps import UNKNOWN, MapFormatError, OccupancyGrid, load_map, save_map

REAL_MAP = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "olin_ac109_1"


def _yaml(folder: Path, image: str, **extra) -> Path:
    meta = {
        "image": image,
        "resolution": 0.05,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
        **extra,
    }
    path = folder / (Path(image).stem + ".yaml")
    path.write_text(yaml.safe_dump(meta))
    return path


def _expected(levels: np.ndarray, mode: str = "trinary", negate: bool = False) -> np.ndarray:
    """map_server's cell values for grey levels in [0, 1], image row order."""
    p = levels if negate else 1.0 - levels
    out = np.full(p.shape, UNKNOWN)
    out[p > 0.65] = 1.0
    out[p < 0.196] = 0.0
    if mode == "scale":
        mid = (p >= 0.196) & (p <= 0.65)
        out[mid] = (p[mid] - 0.196) / (0.65 - 0.196)
    return out


# the levels map_saver writes (0 occupied, 205 unknown, 254 free) and a sweep of greys
LEVELS = np.array([[0, 205, 254, 255], [30, 100, 128, 180], [60, 90, 200, 230]]) / 255.0


def _write_pgm16(path: Path, values: np.ndarray, maxval: int = 65535) -> None:
    header = f"P5\n{values.shape[1]} {values.shape[0]}\n{maxval}\n".encode()
    path.write_bytes(header + values.astype(">u2").tobytes())


@pytest.mark.parametrize("mode", ["trinary", "scale"])
@pytest.mark.parametrize("negate", [False, True])
@pytest.mark.parametrize("fmt", ["png8", "png16", "pgm16", "pgm16_maxval1000"])
def test_every_bit_depth_gives_map_servers_values(tmp_path, fmt, mode, negate):
    if fmt == "png8":
        values = np.round(LEVELS * 255).astype(np.uint8)
        Image.fromarray(values).save(tmp_path / "m.png")
        name, levels = "m.png", values / 255.0
    elif fmt == "png16":
        values = np.round(LEVELS * 65535).astype(np.uint16)
        Image.fromarray(values).save(tmp_path / "m.png")
        name, levels = "m.png", values / 65535.0
    elif fmt == "pgm16":
        values = np.round(LEVELS * 65535).astype(np.uint16)
        _write_pgm16(tmp_path / "m.pgm", values)
        name, levels = "m.pgm", values / 65535.0
    else:  # maxval 1000: the level is value / maxval (205 / 255 sits on free_thresh: moved)
        values = np.round(np.where(LEVELS == 205 / 255, 0.7, LEVELS) * 1000).astype(np.uint16)
        _write_pgm16(tmp_path / "m.pgm", values, maxval=1000)
        name, levels = "m.pgm", values / 1000.0
    grid = load_map(_yaml(tmp_path, name, mode=mode, negate=int(negate)))
    np.testing.assert_allclose(grid.data, np.flipud(_expected(levels, mode, negate)), atol=2e-3)
    # grey (unknown) pixels never turn free, whatever the depth
    if not negate:
        assert grid.data[-1, 1] == UNKNOWN if mode == "trinary" else 0 < grid.data[-1, 1] < 1


def test_sixteen_bit_map_saver_levels_are_occupied_unknown_free(tmp_path):
    values = (np.array([[0, 205, 254]]) * 257).astype(np.uint16)  # 8-bit levels stretched
    Image.fromarray(values).save(tmp_path / "s.png")
    grid = load_map(_yaml(tmp_path, "s.png"))
    assert grid.data.tolist() == [[1.0, UNKNOWN, 0.0]]


@pytest.mark.parametrize("kind", ["RGBA", "LA", "P"])
def test_transparency_is_unknown_in_scale_mode(tmp_path, kind):
    grey = np.array([[0, 128, 254], [0, 128, 254]], dtype=np.uint8)
    alpha = np.array([[255, 255, 255], [0, 100, 0]], dtype=np.uint8)
    if kind == "RGBA":
        img = Image.fromarray(np.dstack([grey, grey, grey, alpha]), mode="RGBA")
    elif kind == "LA":
        img = Image.fromarray(np.dstack([grey, alpha]), mode="LA")
    else:  # a palette image whose index 3 is transparent
        img = Image.fromarray(np.array([[0, 1, 2], [0, 3, 2]], dtype=np.uint8), mode="P")
        img.putpalette([0, 0, 0, 128, 128, 128, 254, 254, 254, 128, 128, 128] + [0] * 756)
        img.info["transparency"] = 3
        alpha = np.array([[255, 255, 255], [255, 0, 255]], dtype=np.uint8)
    img.save(tmp_path / "t.png", **({"transparency": 3} if kind == "P" else {}))
    scale = load_map(_yaml(tmp_path, "t.png", mode="scale"))
    opaque = np.flipud(alpha == 255)
    assert np.all(scale.data[~opaque] == UNKNOWN)
    assert np.all(scale.data[opaque] != UNKNOWN)  # black, mid grey and white, all opaque
    # trinary ignores alpha: the same pixels give occupied / unknown / free by colour
    trinary = load_map(_yaml(tmp_path, "t.png", mode="trinary"))
    row = trinary.data[-1]  # image row 0
    assert row.tolist() == [1.0, UNKNOWN, 0.0]


def test_save_map_round_trips_and_refuses_to_overwrite_another_maps_image(tmp_path):
    data = np.array([[0.0, 1.0, UNKNOWN], [0.1, 0.9, 0.5]])
    grid = OccupancyGrid(data, 0.05, np.array([1.0, 2.0, 0.0]))
    first = save_map(grid, tmp_path / "x.yaml")
    before = (tmp_path / "x.pgm").read_bytes()
    other = OccupancyGrid(np.ones((2, 3)), 0.05)
    with pytest.raises(FileExistsError, match="x.yaml"):
        save_map(other, tmp_path / "x.yml")
    assert (tmp_path / "x.pgm").read_bytes() == before  # untouched
    assert not (tmp_path / "x.yml").exists()
    # an explicit image name works, and both maps still load as saved
    save_map(other, tmp_path / "x.yml", image="x_other.pgm")
    np.testing.assert_array_equal(load_map(tmp_path / "x.yml").data, np.ones((2, 3)))
    back = load_map(first)
    np.testing.assert_array_equal(back.data, [[0.0, 1.0, UNKNOWN], [0.0, 1.0, UNKNOWN]])
    np.testing.assert_array_equal(back.origin, grid.origin)
    # saving the same map again over its own image is fine
    save_map(grid, tmp_path / "x.yaml")


def test_huge_pgm_header_raises_a_map_error_naming_the_file(tmp_path):
    bomb = tmp_path / "bomb.pgm"
    bomb.write_bytes(b"P5\n200000 200000\n255\n" + b"\0" * 64)
    with pytest.raises(MapFormatError, match="bomb.pgm"):
        load_map(_yaml(tmp_path, "bomb.pgm"))
    with pytest.raises(MapFormatError, match="bomb.pgm"):
        load_map(bomb)


def test_truncated_sixteen_bit_pgm_raises_a_map_error(tmp_path):
    (tmp_path / "cut.pgm").write_bytes(b"P5\n40 40\n65535\n" + b"\0" * 10)
    with pytest.raises(MapFormatError, match="cut.pgm"):
        load_map(_yaml(tmp_path, "cut.pgm"))


@pytest.mark.skipif(not REAL_MAP.is_dir(), reason="../shared/data/olin_ac109_1 not present")
def test_real_map_keeps_its_unknown_outside_and_survives_a_round_trip(tmp_path):
    grid = load_map(REAL_MAP / "ac109_1.yaml")
    # the room is mapped, the rest (96 %) is unknown: neither free nor occupied
    assert 0.9 < grid.unknown.mean() < 0.99
    assert not np.any(grid.occupied & grid.unknown) and not np.any(grid.free & grid.unknown)
    # an 8-bit P6 image saved as P5 and read back gives the same trinary map
    back = load_map(save_map(grid, tmp_path / "ac109.yaml"))
    np.testing.assert_array_equal(back.data, grid.data)
    # the same map stretched to 16 bits reads the same
    rgb = np.asarray(Image.open(REAL_MAP / "ac109_1.pgm").convert("L"), dtype=np.uint16) * 257
    Image.fromarray(rgb).save(tmp_path / "ac109_16.png")
    meta = yaml.safe_load((REAL_MAP / "ac109_1.yaml").read_text())
    meta["image"] = "ac109_16.png"
    (tmp_path / "ac109_16.yaml").write_text(yaml.safe_dump(meta))
    np.testing.assert_array_equal(load_map(tmp_path / "ac109_16.yaml").data, grid.data)
