"""What a call did to its arguments, seen in the worker and replayed in the grader.

Arguments reach the worker as pickled copies and results come back as fresh
arrays, so, left alone, a hidden test could never see that a student function
modified its input in place or returned a read-only array or a view of its
input. The worker therefore watches each call (:class:`Watch`) and sends, with
the result, a plain-data *observation*::

    {"modified": [(path, new_value), ...],      # argument arrays changed in place
     "readonly": [path, ...],                   # result arrays that are not writeable
     "aliases":  [(path, "same", source), ...   # the result *is* that argument array
                  (path, "view", source, offset, shape, strides, source_strides), ...]}

A ``path`` is a tuple of steps ``("i", index)``, ``("k", key)`` or
``("a", attribute)`` from ``(args, kwargs)`` (arguments) or from the result;
a ``source`` is ``("arg", path)`` or ``("result", path)``. :func:`replay`
applies it in the grader to the caller's own objects, so the hidden test sees
what it would have seen in-process:

- a modified argument array is overwritten with the worker's final value
  (``np.copyto``, only when shape and dtype match and it is writeable);
- a read-only result is made read-only;
- a result that is an argument becomes the caller's argument itself; a view
  of an argument (or of an earlier result array) becomes the same view of the
  caller's array, rebuilt only when the source array is contiguous with the
  worker's strides, the view lies inside its buffer, and the rebuilt view holds
  exactly the bytes the worker returned.

Anything else -- a view whose source is not contiguous, two results that
overlap without one containing the other, in-place changes to lists or to
objects other than arrays -- is not replayed: the result stays a fresh,
writeable array (documented in docs/grading.md section 2).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

__all__ = ["Watch", "replay"]

#: Deepest nesting of containers searched for arrays, and most arrays watched per call.
MAX_DEPTH = 8
MAX_ARRAYS = 256
#: Most objects visited when looking for arrays in one call's arguments or result.
MAX_NODES = 100_000

Path = tuple  # of ("i", int) | ("k", str | int) | ("a", str)


def arrays_in(
    value: Any, path: Path = (), depth: int = 0, budget: list | None = None
) -> Iterator[tuple[Path, np.ndarray]]:
    """Every numpy array in ``value`` (through tuples, lists, dicts, dataclasses), with its path.

    The walk is bounded: at most :data:`MAX_NODES` objects are visited and a container
    met twice (``[a] * 10`` nested 8 deep is 1e8 leaves from 9 lists) is walked once,
    so a result built to be expensive to walk costs the worker nothing much.
    """
    if budget is None:
        budget = [MAX_NODES, set()]
    if budget[0] <= 0:
        return
    budget[0] -= 1
    if isinstance(value, np.ndarray):
        yield path, value
        return
    if depth >= MAX_DEPTH:
        return
    if isinstance(value, (tuple, list, dict)) or (
        dataclasses.is_dataclass(value) and not isinstance(value, type)
    ):
        if id(value) in budget[1]:
            return
        budget[1].add(id(value))
    if isinstance(value, (tuple, list)):
        for index, item in enumerate(value):
            yield from arrays_in(item, (*path, ("i", index)), depth + 1, budget)
    elif isinstance(value, dict):
        for key, item in value.items():
            if isinstance(key, (str, int)) and not isinstance(key, bool):
                yield from arrays_in(item, (*path, ("k", key)), depth + 1, budget)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            yield from arrays_in(
                getattr(value, f.name, None), (*path, ("a", f.name)), depth + 1, budget
            )


def _bounds(a: np.ndarray) -> tuple[int, int]:
    """Lowest and one-past-highest byte address ``a`` touches (a non-empty array)."""
    start = a.__array_interface__["data"][0]
    low = start + sum(min(0, (n - 1) * s) for n, s in zip(a.shape, a.strides, strict=True))
    high = start + sum(max(0, (n - 1) * s) for n, s in zip(a.shape, a.strides, strict=True))
    return low, high + a.itemsize


def _contiguous(a: np.ndarray) -> bool:
    return a.size > 0 and (a.flags.c_contiguous or a.flags.f_contiguous)


def _address(a: np.ndarray) -> int:
    return a.__array_interface__["data"][0]


class Watch:
    """Snapshot of a call's argument arrays, taken in the worker before the call."""

    def __init__(
        self, args: tuple, kwargs: dict, snapshot: Callable[[np.ndarray], Any] | None = None
    ) -> None:
        # ``snapshot(a)``: an untouched copy of ``a`` kept anyway (the worker's slot of an
        # array the grader sent before, wire.arrays), or None to copy it here.
        self.inputs = [
            (path, a, _snapshot(a, snapshot)) for path, a in _first(arrays_in((args, kwargs)))
        ]

    def report(self, result: Any) -> dict:
        """The observation of the call that returned ``result`` (plain data)."""
        modified = [
            (path, a)
            for path, a, before in self.inputs
            if a.shape != before.shape or a.dtype != before.dtype or not _same_bytes(a, before)
        ]
        results = list(_first(arrays_in(result)))
        readonly = [path for path, r in results if not r.flags.writeable]
        aliases = []
        seen: list[tuple[str, Path, np.ndarray]] = [("arg", p, a) for p, a, _ in self.inputs]
        for path, r in results:
            alias = _alias(r, seen)
            if alias is not None:
                aliases.append((path, *alias))
            seen.append(("result", path, r))
        return {"modified": modified, "readonly": readonly, "aliases": aliases}


def _snapshot(a: np.ndarray, kept: Callable[[np.ndarray], Any] | None) -> np.ndarray:
    before = kept(a) if kept is not None else None
    return a.copy() if before is None else before


def _first(found: Iterator[tuple[Path, np.ndarray]]) -> list[tuple[Path, np.ndarray]]:
    out = []
    for item in found:
        if len(out) == MAX_ARRAYS:
            break
        out.append(item)
    return out


def _same_bytes(a: np.ndarray, b: np.ndarray) -> bool:
    return np.array_equal(
        np.ascontiguousarray(a).reshape(-1).view(np.uint8),
        np.ascontiguousarray(b).reshape(-1).view(np.uint8),
    )


def _alias(r: np.ndarray, seen: list[tuple[str, Path, np.ndarray]]) -> tuple | None:
    if r.size == 0:
        return None
    for kind, path, a in seen:
        if r is a:
            return ("same", (kind, path)) if kind == "arg" else None  # pickle keeps result identity
    low, high = _bounds(r)
    for kind, path, a in seen:
        if not _contiguous(a):
            continue
        a_low, a_high = _bounds(a)
        if a_low <= low and high <= a_high:
            offset = _address(r) - a_low
            return (
                "view",
                (kind, path),
                int(offset),
                tuple(int(n) for n in r.shape),
                tuple(int(s) for s in r.strides),
                tuple(int(s) for s in a.strides),
            )
    return None


# --- the grader's side ---------------------------------------------------------------------------


class _Unresolved(Exception):
    pass


def _get(root: Any, path: Any) -> Any:
    if not isinstance(path, tuple):
        raise _Unresolved
    value = root
    for step in path:
        if not (isinstance(step, tuple) and len(step) == 2):
            raise _Unresolved
        kind, key = step
        try:
            if kind == "i" and isinstance(value, (tuple, list)) and isinstance(key, int):
                value = value[key]
            elif kind == "k" and isinstance(value, dict):
                value = value[key]
            elif (
                kind == "a"
                and isinstance(key, str)
                and dataclasses.is_dataclass(value)
                and key in {f.name for f in dataclasses.fields(value)}
            ):
                value = getattr(value, key)
            else:
                raise _Unresolved
        except (KeyError, IndexError, TypeError) as exc:
            raise _Unresolved from exc
    return value


def _put(root: Any, path: tuple, new: Any) -> Any:
    """``root`` with the value at ``path`` replaced (tuples rebuilt, the rest changed in place)."""
    if not path:
        return new
    (_, key), rest = path[0], path[1:]
    child = _get(root, (path[0],))
    replaced = _put(child, rest, new)
    if isinstance(root, tuple):
        items = list(root)
        items[key] = replaced
        return type(root)(items) if type(root) is tuple else root
    if isinstance(root, (list, dict)):
        root[key] = replaced
    else:
        object.__setattr__(root, key, replaced)  # a dataclass the codec just built
    return root


def replay(result: Any, observation: Any, args: tuple, kwargs: dict) -> Any:
    """Apply a worker's observation to the caller's arguments and the decoded result.

    Malformed or unsafe entries are ignored (the observation comes from the
    untrusted worker): nothing here builds a view outside a caller's array.

    Returns
    -------
    The result the hidden test gets.
    """
    if not isinstance(observation, dict):
        return result
    inputs = (args, kwargs)
    for entry in _entries(observation, "modified"):
        try:
            path, new = entry
            target = _get(inputs, path)
        except (_Unresolved, TypeError, ValueError):
            continue
        if (
            isinstance(target, np.ndarray)
            and isinstance(new, np.ndarray)
            and target.shape == new.shape
            and target.dtype == new.dtype
            and target.flags.writeable
        ):
            np.copyto(target, new)
    for entry in _entries(observation, "aliases"):
        try:
            result = _replay_alias(result, inputs, entry)
        except (_Unresolved, TypeError, ValueError, IndexError, KeyError):
            continue
    for path in _entries(observation, "readonly"):
        try:
            target = _get(result, path)
        except _Unresolved:
            continue
        if isinstance(target, np.ndarray):
            target.setflags(write=False)
    return result


def _entries(observation: dict, key: str) -> list:
    value = observation.get(key, [])
    return value if isinstance(value, list) else []


def _replay_alias(result: Any, inputs: tuple, entry: Any) -> Any:
    path, how, (kind, source_path), *layout = entry
    decoded = _get(result, path)
    if not isinstance(decoded, np.ndarray) or kind not in ("arg", "result"):
        return result
    source = _get(inputs if kind == "arg" else result, source_path)
    if not isinstance(source, np.ndarray):
        return result
    if how == "same":
        if source.shape == decoded.shape and source.dtype == decoded.dtype:
            return _put(result, path, source)
        return result
    if how != "view":
        return result
    offset, shape, strides, source_strides = layout
    view = _view(source, decoded, offset, shape, strides, source_strides)
    return result if view is None else _put(result, path, view)


def _view(
    source: np.ndarray,
    decoded: np.ndarray,
    offset: Any,
    shape: Any,
    strides: Any,
    source_strides: Any,
) -> np.ndarray | None:
    """``decoded`` rebuilt as a view of the caller's ``source``, or None when that is unsafe."""
    ints = (offset, *shape, *strides, *source_strides)
    if not all(isinstance(n, int) and not isinstance(n, bool) for n in ints):
        return None
    if (
        not _contiguous(source)
        or tuple(source.strides) != tuple(source_strides)
        or tuple(shape) != decoded.shape
        or len(strides) != len(shape)
        or decoded.size == 0
    ):
        return None
    itemsize = decoded.dtype.itemsize
    low = offset + sum(min(0, (n - 1) * s) for n, s in zip(shape, strides, strict=True))
    high = offset + sum(max(0, (n - 1) * s) for n, s in zip(shape, strides, strict=True)) + itemsize
    if low < 0 or high > source.nbytes:
        return None
    raw = source.reshape(-1, order="A").view(np.uint8)  # a view: source is contiguous
    if raw.size != source.nbytes or _address(raw) != _bounds(source)[0]:
        return None
    view = np.ndarray(shape, dtype=decoded.dtype, buffer=raw, offset=offset, strides=strides)
    if not _same_bytes(view, decoded):
        return None  # not what the worker returned: keep the decoded copy
    if not decoded.flags.writeable:
        view.setflags(write=False)
    return view
