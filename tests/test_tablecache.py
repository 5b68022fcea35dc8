"""Tests of robolab.tablecache, and of the MCL likelihood table cached through it."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from robolab import tablecache
from robolab.maps import OccupancyGrid
from robolab.tablecache import cached_table, freeze, is_frozen


class Builds:
    """A build function that counts its calls."""

    def __init__(self, source):
        self.source, self.calls = source, 0

    def __call__(self):
        self.calls += 1
        return self.source * 2.0


def test_is_frozen_needs_every_base_read_only():
    a = np.arange(6.0)
    assert not is_frozen(a)
    view = a[1:]
    view.flags.writeable = False
    assert not is_frozen(view)  # its base can still be written
    f = freeze(a)
    assert is_frozen(f) and f is not a and f.base is None
    np.testing.assert_array_equal(f, a)
    sub = f[2:]
    assert is_frozen(sub)  # a view of a frozen array
    assert not is_frozen([1.0, 2.0]) and not is_frozen(None)
    with pytest.raises(ValueError):
        f[0] = 5.0


def test_frozen_sources_are_built_once_per_key():
    d = freeze(np.ones((3, 4)))
    build = Builds(d)
    t1 = cached_table(d, ("k", 1.0), build)
    t2 = cached_table(d, ("k", 1.0), build)
    assert t1 is t2 and build.calls == 1
    assert not t1.flags.writeable  # a shared table cannot be altered by one caller
    t3 = cached_table(d, ("k", 2.0), build)  # other parameters: another table
    assert t3 is not t1 and build.calls == 2
    other = freeze(np.ones((3, 4)))  # equal values, another array: its own entry
    assert cached_table(other, ("k", 1.0), Builds(other)) is not t1


def test_writeable_sources_are_rebuilt_when_their_content_changes():
    d = np.ones((2, 2))
    build = Builds(d)
    first = cached_table(d, "k", build)
    assert cached_table(d, "k", build) is first and build.calls == 1
    d[0, 0] = 7.0  # changed in place: its bytes no longer match
    second = cached_table(d, "k", build)
    assert build.calls == 2 and second[0, 0] == 14.0 and first[0, 0] == 2.0
    assert not second.flags.writeable


def test_unfrozen_sources_are_matched_by_bytes_shape_and_dtype(monkeypatch):
    monkeypatch.setattr(tablecache, "_BY_CONTENT", [])
    d = np.arange(6.0).reshape(2, 3)
    t = cached_table(d, "k", Builds(d))
    copy = d.copy()  # a fresh array every call, as the grading worker decodes its arguments
    assert cached_table(copy, "k", Builds(copy)) is t
    for other in (d.reshape(3, 2), d.astype(np.float32), np.where(d == 0, -0.0, d)):
        build = Builds(other)  # same values, other shape / dtype / bytes (-0.0): rebuilt
        assert cached_table(other, "k", build) is not t and build.calls == 1
    assert len(tablecache._BY_CONTENT) == tablecache.MAX_BY_CONTENT


def test_content_cache_can_be_switched_off(monkeypatch):
    monkeypatch.setattr(tablecache, "MAX_BY_CONTENT", 0)
    d = np.ones(3)
    build = Builds(d)
    cached_table(d, "k", build)
    cached_table(d, "k", build)
    assert build.calls == 2


def test_entries_die_with_their_source_and_are_bounded():
    d = freeze(np.zeros(5))
    for k in range(tablecache.MAX_TABLES_PER_ARRAY + 3):
        cached_table(d, k, Builds(d))
    assert len(tablecache._TABLES[id(d)][1]) == tablecache.MAX_TABLES_PER_ARRAY
    ident = id(d)
    del d
    gc.collect()
    assert ident not in tablecache._TABLES


# -- the MCL likelihood table ---------------------------------------------------------------------
def _scan_and_particles(grid, rng):
    from robolab.raycast import cast_rays
    from solutions import mcl

    angles = np.linspace(-np.pi, np.pi, 40, endpoint=False)
    ranges = cast_rays(grid, [2.1, 1.7, 0.3], angles, 3.0)[0]
    ranges[::7] = np.inf  # some max-range beams
    scan = {"ranges": ranges, "angles": angles, "range_min": 0.05, "range_max": 3.0}
    return scan, mcl.init_uniform(grid, 300, rng)


def _grid(rng):
    data = np.zeros((40, 50))
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 1.0
    data[rng.integers(1, 39, 30), rng.integers(1, 49, 30)] = 1.0
    return OccupancyGrid(data, 0.1)


def test_mcl_cached_table_equals_the_rebuilt_one(monkeypatch):
    from solutions import mcl

    monkeypatch.setattr(tablecache, "MAX_BY_CONTENT", 0)  # the writeable copy: rebuilt
    rng = np.random.default_rng(0)
    grid = _grid(rng)
    scan, particles = _scan_and_particles(grid, rng)
    field = mcl.likelihood_field(grid, 0.15, 1.0)
    assert is_frozen(field["distance"])  # so that likelihood_field_model can cache
    writeable = {k: np.array(v) if isinstance(v, np.ndarray) else v for k, v in field.items()}
    for params in (
        {"z_hit": 0.9, "z_rand": 0.1},
        {"z_hit": 0.5, "z_rand": 0.5},
        {"z_hit": 1.0, "z_rand": 0.0},
    ):
        cached = [mcl.likelihood_field_model(scan, particles, field, params) for _ in range(2)]
        rebuilt = mcl.likelihood_field_model(scan, particles, writeable, params)
        np.testing.assert_array_equal(cached[0], cached[1])
        np.testing.assert_array_equal(cached[0], rebuilt)  # no stale table across parameters
    # the scan's range_max is part of the table (z_rand / z_max): a new one is used
    other = {**scan, "range_max": 6.0}
    np.testing.assert_array_equal(
        mcl.likelihood_field_model(other, particles, field, {"z_rand": 0.2}),
        mcl.likelihood_field_model(other, particles, writeable, {"z_rand": 0.2}),
    )


def test_mcl_writeable_field_changes_are_seen():
    # A student's field (writeable arrays) changed in place between calls: the model
    # must score with the new distances, never with a table cached from the old ones.
    from solutions import mcl

    rng = np.random.default_rng(1)
    grid = _grid(rng)
    scan, particles = _scan_and_particles(grid, rng)
    field = mcl.likelihood_field(grid, 0.15, 1.0)
    writeable = {k: np.array(v) if isinstance(v, np.ndarray) else v for k, v in field.items()}
    before = mcl.likelihood_field_model(scan, particles, writeable, {})
    writeable["distance"][:] = 1.0  # everything at max_dist
    after = mcl.likelihood_field_model(scan, particles, writeable, {})
    assert not np.allclose(before, after)
    assert np.ptp(after) < 1e-9  # every endpoint now scores the same


def test_mcl_bad_field_is_still_refused_on_a_cache_miss_and_hit():
    from solutions import mcl

    rng = np.random.default_rng(2)
    grid = _grid(rng)
    scan, particles = _scan_and_particles(grid, rng)
    bad = mcl.likelihood_field(grid, 0.15, 1.0)
    bad["distance"] = freeze(np.full(grid.shape, np.nan))
    for _ in range(2):
        with pytest.raises(ValueError, match="distance"):
            mcl.likelihood_field_model(scan, particles, bad, {})
