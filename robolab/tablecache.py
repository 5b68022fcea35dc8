"""Per-cell tables derived from a read-only map array, computed once and cached.

A filter step that needs a table over the whole map (MCL's log-likelihood of
every cell of a likelihood field, for one sensor model's parameters) should
not rebuild it on every call: that makes each step cost in proportion to the
map instead of to the particles and beams. :func:`cached_table` keeps such
tables per source array and parameters.

Two caches, both exact:

* per array, for arrays that cannot change: a **read-only** array
  (``flags.writeable`` false) whose memory is not reachable through a writeable
  base array (:func:`is_frozen`). :func:`freeze` makes such an array (the
  reference solution of lab 05 returns its likelihood field's arrays frozen).
  Entries are dropped when their source array is garbage collected.
* by content, for any other array (a writeable field, or a field rebuilt from
  bytes on every call, as the grading worker receives its arguments): the
  :data:`MAX_BY_CONTENT` most recent sources are kept as bytes, and a source whose
  shape, dtype and bytes equal one of them (one ``memcmp``, about 0.1 ms for a
  map of 100,000 cells against 5-13 ms to rebuild MCL's table) gets its tables.
  An array changed in place no longer matches and gets a new table.

Examples
--------
>>> import numpy as np
>>> d = freeze(np.arange(6.0).reshape(2, 3))
>>> t = cached_table(d, ("square",), lambda: d**2)
>>> t is cached_table(d, ("square",), lambda: d**2)
True
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Hashable

import numpy as np

__all__ = ["cached_table", "freeze", "is_frozen"]

#: Tables kept per source array (different parameters); the oldest is dropped beyond this.
MAX_TABLES_PER_ARRAY = 4
#: Sources that are not frozen whose tables are kept, matched by content (0: never cached).
MAX_BY_CONTENT = 2

# The most recent first: (shape, dtype, bytes of the source, {key: table}).
_BY_CONTENT: list[tuple[tuple, np.dtype, bytes, dict]] = []

# id(source) -> (weak reference to source, {key: table}). Arrays are unhashable, hence
# keyed by id and checked through the weak reference (an id can be reused after death).
_TABLES: dict[int, tuple[weakref.ref, dict]] = {}


def freeze(array) -> np.ndarray:
    """A read-only float copy of ``array`` that owns its memory (so :func:`is_frozen` holds)."""
    out = np.array(array, dtype=float, copy=True)
    out.flags.writeable = False
    return out


def is_frozen(array) -> bool:
    """Whether ``array`` is a numpy array that nothing can write to (itself and every base)."""
    if not isinstance(array, np.ndarray):
        return False
    a = array
    while isinstance(a, np.ndarray):
        if a.flags.writeable:
            return False
        a = a.base
    # a base that is not an ndarray (bytes, mmap, a foreign buffer) may be written elsewhere
    return a is None or isinstance(a, bytes)


def cached_table(source: np.ndarray, key: Hashable, build: Callable[[], np.ndarray]) -> np.ndarray:
    """``build()``, cached per ``(source, key)`` when ``source`` is frozen.

    Parameters
    ----------
    source : numpy.ndarray
        The array the table is derived from.
    key : hashable
        Everything else the table depends on (parameters, as plain numbers).
    build : callable
        Computes the table from ``source`` and ``key``; called on a cache miss.

    Returns
    -------
    numpy.ndarray
        The table, read-only when it comes from (or went into) the cache.
    """
    if not is_frozen(source):
        return _by_content(source, key, build)
    entry = _TABLES.get(id(source))
    if entry is None or entry[0]() is not source:
        entry = (weakref.ref(source, _forget(id(source))), {})
        _TABLES[id(source)] = entry
    tables = entry[1]
    return _table(tables, key, build)


def _by_content(source, key, build):
    """``build()``, cached for the last :data:`MAX_BY_CONTENT` sources of equal bytes."""
    if MAX_BY_CONTENT < 1 or not isinstance(source, np.ndarray):
        return build()
    data = source.tobytes()  # C order: equal bytes, shape and dtype mean an equal array
    for i, entry in enumerate(_BY_CONTENT):
        if entry[0] == source.shape and entry[1] == source.dtype and entry[2] == data:
            _BY_CONTENT.insert(0, _BY_CONTENT.pop(i))
            tables = entry[3]
            break
    else:
        tables = {}
        _BY_CONTENT.insert(0, (source.shape, source.dtype, data, tables))
        del _BY_CONTENT[MAX_BY_CONTENT:]
    return _table(tables, key, build)


def _forget(ident: int):
    def callback(ref: weakref.ref) -> None:
        entry = _TABLES.get(ident)
        if entry is not None and entry[0] is ref:
            del _TABLES[ident]

    return callback


def _table(tables: dict, key, build):
    """``tables[key]``, built read-only on first use (at most MAX_TABLES_PER_ARRAY kept)."""
    table = tables.get(key)
    if table is None:
        table = np.asarray(build())
        table.flags.writeable = False
        if len(tables) >= MAX_TABLES_PER_ARRAY:
            tables.pop(next(iter(tables)))
        tables[key] = table
    return table
