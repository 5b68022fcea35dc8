"""Decode what a worker sends back, accepting plain data only, at a cost the grader bounds.

Results cross from the (untrusted) worker to the grader as pickles, because
pickle is fast for numpy arrays. Unpickling runs whatever callable the stream
names, so the grader never uses :func:`pickle.loads` on worker output: it uses
:func:`loads`, a restricted unpickler that

* knows an allow-list of harmless constructors (numpy arrays from a buffer,
  numpy scalars, dtypes of a fixed set of plain kinds, ``complex``, ``slice``,
  ``range``, sets, ``bytearray``, ``Fraction`` and registered robolab
  dataclasses, among them :class:`SparseMatrix`, the form in which a scipy.sparse
  result crosses), each wrapped so its arguments are checked *before* it runs;
* executes only the opcodes a protocol-5 pickle of plain data uses, and never
  calls ``__setstate__``: a numpy dtype's state must be exactly the state of
  the plain dtype its constructor built (structured, subarray, object, void,
  datetime and non-native dtypes are refused, so a field offset outside the
  item can never be smuggled in);
* decodes under a :class:`DecodeLimits` budget checked before anything is
  allocated or hashed: message bytes, opcodes, buffer lengths, integer and
  Fraction bit sizes, ``range`` lengths, string lengths, and a work budget
  proportional to the message's size, charged before any operation whose cost
  is not bounded by the bytes that spell it (the stream can refer to one object
  again and again through the memo): hashing dict keys and set items, the gcd
  normalising a Fraction. Bytearrays copied from one buffer may not hold more
  bytes than the message. Few keys may share a hash.

After unpickling, the value is walked once more: allowed types only, nesting
depth, no value containing itself, and its *expanded* size -- every element
counted as often as it is referenced, so a list nested 8 deep of ``[a] * 10``
counts 1e8 leaves although its message has 200 bytes -- within the budget.
Every cost is thus linear in the message (at most a small multiple of
decoding a plain message of the same size) and bounded by the grader's own
limits, so no memory or time limit is needed around the decode itself. The
opcode engine is :mod:`robolab.grading.wire.unpickler`; this module holds what is
allowed and the final walk.
"""

from __future__ import annotations

import dataclasses
import fractions
import io
import math
import pickle
import re
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from robolab.grading.wire.unpickler import (
    LIMITS,
    MAX_DEPTH,
    CodecError,
    DecodeLimits,
    active,
    check_int,
    decode,
    short,
)

__all__ = [
    "LIMITS",
    "MAX_DEPTH",
    "SparseMatrix",
    "CodecError",
    "DecodeLimits",
    "check_plain",
    "dumps",
    "loads",
    "register_dataclass",
    "registered_dataclasses",
]

#: Pickle protocol of the wire format; 5 stores numpy arrays as one flat buffer.
PROTOCOL = 5

_PLAIN_SCALARS = (type(None), bool, int, float, complex, fractions.Fraction, str, bytes, bytearray)
_CONTAINERS = (list, tuple, set, frozenset)
#: Numpy kinds a result may hold, as the dtype constructor's argument.
_DTYPE_NAMES = frozenset("b1 i1 i2 i4 i8 u1 u2 u4 u8 f2 f4 f8 f16 c8 c16 c32".split())
#: Strings and bytes arrays: "U12", "S4" (size in characters or bytes).
_FLEXIBLE_DTYPE = re.compile(r"[US]([1-9][0-9]{0,3})")
_MAX_DIMENSIONS = 32


# --- constructors the stream may call, each checking its arguments first ------------------------


def plain_dtype(dtype: Any) -> np.dtype:
    """``dtype`` itself when it is a plain numeric, bool, string or bytes dtype; else CodecError."""
    if not isinstance(dtype, np.dtype):
        raise CodecError(f"expected a numpy dtype, got {type(dtype).__name__}")
    if dtype.hasobject:
        raise CodecError(f"numpy arrays of dtype {dtype} (holding Python objects) are not accepted")
    if dtype.fields is not None or dtype.subdtype is not None:
        raise CodecError(f"numpy arrays of structured dtype {dtype} are not accepted")
    if dtype.kind not in "biufcUS" or not dtype.isnative:
        raise CodecError(f"numpy arrays of dtype {dtype.str} are not accepted")
    return dtype


def _dtype(name: Any, align: Any = False, copy: Any = True) -> np.dtype:
    if not (type(name) is str and (name in _DTYPE_NAMES or _FLEXIBLE_DTYPE.fullmatch(name))):
        raise CodecError(f"numpy dtype {short(name)} is not accepted (plain numbers only)")
    if align is not False or type(copy) is not bool:
        raise CodecError("numpy dtypes with alignment options are not accepted")
    return plain_dtype(np.dtype(name))


def _frombuffer(buffer: Any, dtype: Any, shape: Any, order: Any) -> np.ndarray:
    from numpy._core.numeric import _frombuffer as real

    dtype = plain_dtype(dtype)
    if type(buffer) not in (bytes, bytearray):
        raise CodecError("a numpy array must be rebuilt from bytes")
    if (
        type(shape) is not tuple
        or len(shape) > _MAX_DIMENSIONS
        or not all(type(n) is int and 0 <= n and n.bit_length() < 63 for n in shape)
    ):
        raise CodecError(f"a numpy array of shape {short(shape)} is not accepted")
    if math.prod(shape) * dtype.itemsize != len(buffer) or order not in ("C", "F"):
        raise CodecError("a numpy array's shape does not match its data")
    return real(buffer, dtype, shape, order)


def _scalar(dtype: Any, *args: Any) -> np.generic:
    from numpy._core.multiarray import scalar as real

    dtype = plain_dtype(dtype)
    if len(args) != 1 or type(args[0]) is not bytes or len(args[0]) != dtype.itemsize:
        raise CodecError("a numpy scalar must be rebuilt from its bytes")
    return real(dtype, *args)


#: How Python <= 3.11 pickles a Fraction: its str(), "n" or "n/d" in decimal digits.
_FRACTION_TEXT = re.compile(r"-?[0-9]{1,4300}(/[0-9]{1,4300})?")


def _words(bits: int) -> int:
    return 1 + bits // 64


def _fraction(numerator: Any, denominator: Any = 1) -> fractions.Fraction:
    # Python 3.12+ pickles Fraction(numerator, denominator), 3.10-3.11 Fraction("n/d").
    # Accept exactly those two forms, so the constructor's float, Decimal and
    # scientific-notation paths are never reached; bound the sizes before the gcd.
    # The stream can name one big int or text again and again through the memo, so the
    # gcd (quadratic in the words of the two parts) and the parsing of decimal text
    # (quadratic too) are charged to the message's work budget before they run.
    unpickler = active()
    if type(numerator) is str and denominator == 1 and _FRACTION_TEXT.fullmatch(numerator):
        top, _, bottom = numerator.partition("/")
        n, d = _words(len(top) * 10 // 3), _words(len(bottom) * 10 // 3)
        unpickler.charge(n * n + d * d + n * d, "Fractions (to parse and normalise)")
        return fractions.Fraction(numerator)
    if type(numerator) is not int or type(denominator) is not int:
        raise CodecError("a Fraction must be built from two ints or their 'n/d' text")
    check_int(numerator, unpickler.limits)
    check_int(denominator, unpickler.limits)
    unpickler.charge(
        _words(numerator.bit_length()) * _words(denominator.bit_length()),
        "Fractions (to normalise)",
    )
    return fractions.Fraction(numerator, denominator)


def _complex(real: Any = 0.0, imag: Any = 0.0) -> complex:
    if type(real) not in (int, float) or type(imag) not in (int, float):
        raise CodecError("a complex number must be built from two floats")
    return complex(real, imag)


def _slice(*args: Any) -> slice:
    if len(args) > 3 or not all(a is None or type(a) is int for a in args):
        raise CodecError("a slice must be built from ints or None")
    for a in args:
        if a is not None:
            check_int(a, active().limits)
    return slice(*args)


def _range(*args: Any) -> range:
    if not 1 <= len(args) <= 3 or not all(type(a) is int and a.bit_length() <= 63 for a in args):
        raise CodecError("a range must be built from at most three 64-bit ints")
    value = range(*args)
    if len(value) > active().limits.max_elements:
        raise CodecError(
            f"a range of {len(value)} elements is too large "
            f"(at most {active().limits.max_elements} are accepted)"
        )
    return value


def _bytearray(data: Any = b"") -> bytearray:
    if type(data) is not bytes:
        raise CodecError("a bytearray must be built from bytes")
    # The memo can name one buffer many times: every copy must be paid for by message bytes.
    unpickler = active()
    unpickler.copied += len(data)
    if unpickler.copied > unpickler.size:
        raise CodecError("the result's bytearrays hold more bytes than its message")
    return bytearray(data)


def _set(items: Any = ()) -> set:
    return active().hashed(set(), items)


def _frozenset(items: Any = ()) -> frozenset:
    return frozenset(active().hashed(set(), items))


# (module, name) -> constructor. Everything the stream can call is one of these.
_ALLOWED: dict[tuple[str, str], Callable[..., Any]] = {
    ("builtins", "complex"): _complex,
    ("builtins", "slice"): _slice,
    ("builtins", "range"): _range,
    ("builtins", "set"): _set,
    ("builtins", "frozenset"): _frozenset,
    ("builtins", "bytearray"): _bytearray,
    ("fractions", "Fraction"): _fraction,
    ("numpy", "dtype"): _dtype,
    ("numpy._core.numeric", "_frombuffer"): _frombuffer,
    ("numpy.core.numeric", "_frombuffer"): _frombuffer,
    ("numpy._core.multiarray", "scalar"): _scalar,
    ("numpy.core.multiarray", "scalar"): _scalar,
}

class _Dataclasses(dict):
    """The registered dataclasses; a class of a default module not yet imported (robolab.maps,
    robolab.bag...) is registered when the decoder first looks it up, so that a plain result
    imports nothing and is not scanned for module names (an MCL answer is 0.6 MB)."""

    def get(self, key: Any, default: Any = None) -> Any:
        found = super().get(key)
        if found is None and type(key) is tuple and len(key) == 2 and type(key[0]) is str:
            if key[0].startswith(_DEFAULT_MODULES):
                _register_defaults(key[0].encode())
                found = super().get(key)
        return default if found is None else found


_DATACLASSES: dict[tuple[str, str], type] = _Dataclasses()


def register_dataclass(cls: type) -> type:
    """Allow instances of a robolab dataclass to cross the process boundary.

    Its fields must themselves be plain data; they are checked on decoding.

    Parameters
    ----------
    cls : type
        A dataclass defined in a ``robolab`` module.

    Returns
    -------
    type
        ``cls``, so this can be used as a decorator.

    Raises
    ------
    TypeError
        When ``cls`` is not a dataclass of the robolab package.
    """
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise TypeError(f"only dataclasses can be registered, got {cls!r}")
    if not cls.__module__.split(".")[0] == "robolab":
        raise TypeError(
            f"only robolab dataclasses can be registered, got {cls.__module__}.{cls.__qualname__}"
        )
    _DATACLASSES[(cls.__module__, cls.__qualname__)] = cls
    return cls


def registered_dataclasses() -> list[type]:
    """The dataclasses accepted by :func:`loads` (after registering the defaults)."""
    _register_defaults()
    return list(_DATACLASSES.values())


#: Modules whose dataclasses are accepted by default (registered on first use).
_DEFAULT_MODULES = ("robolab.maps", "robolab.bag", "robolab.datasets.g2o")
_defaults_registered: set[str] = set()


def _register_defaults(data: bytes | None = None) -> None:
    """Register the default modules' dataclasses: all of them, or those ``data`` names."""
    # Imported lazily: the bag module pulls in `rosbags`, and it may not exist yet.
    import importlib

    if len(_defaults_registered) == len(_DEFAULT_MODULES) or (
        data is not None and b"robolab." not in data
    ):
        return  # one scan of a large message (an array's bytes) instead of one per module
    for module_name in _DEFAULT_MODULES:
        if module_name in _defaults_registered or (
            data is not None and module_name.encode() not in data
        ):
            continue
        _defaults_registered.add(module_name)
        try:
            module = importlib.import_module(module_name)
        except Exception:  # noqa: BLE001 - an optional module failing to import only narrows the list
            continue
        for value in vars(module).values():
            if (
                isinstance(value, type)
                and dataclasses.is_dataclass(value)
                and (value.__module__ + ".").startswith(module_name + ".")
            ):
                register_dataclass(value)


def _registered(kind: type) -> bool:
    return _DATACLASSES.get((kind.__module__, kind.__qualname__)) is kind


@dataclasses.dataclass(frozen=True, eq=False)
class SparseMatrix:
    """A scipy.sparse matrix as it crosses the process boundary: its COO triplets.

    The worker sends every scipy.sparse result in this form (:func:`dumps`), because
    scipy's own pickles run constructors the decoder does not allow. The grader reads
    it back with :meth:`toarray` or :meth:`tosparse`, as it would the original; both
    check the triplets first (they come from an untrusted process).
    """

    shape: tuple
    row: np.ndarray
    col: np.ndarray
    data: np.ndarray
    format: str

    @classmethod
    def of(cls, matrix: Any) -> SparseMatrix:
        """The triplets of a scipy.sparse matrix or array (duplicates kept, as stored)."""
        coo = matrix.tocoo()
        return cls(
            tuple(int(n) for n in coo.shape),
            np.asarray(coo.row, dtype=np.int64),
            np.asarray(coo.col, dtype=np.int64),
            np.asarray(coo.data),
            str(matrix.format),
        )

    @property
    def nnz(self) -> int:
        return int(np.asarray(self.data).size)

    def _checked(
        self, max_cells: float
    ) -> tuple[tuple[int, int], np.ndarray, np.ndarray, np.ndarray]:
        shape = self.shape
        if not (
            isinstance(shape, tuple)
            and len(shape) == 2
            and all(type(n) is int and 0 <= n for n in shape)
        ):
            raise CodecError(
                f"a sparse matrix's shape must be two non-negative ints, got {shape!r}"
            )
        if math.prod(shape) > max_cells:
            raise CodecError(f"a sparse matrix of shape {shape} is too large to read here")
        row, col, data = (np.asarray(a).reshape(-1) for a in (self.row, self.col, self.data))
        if (
            not (row.size == col.size == data.size)
            or row.dtype.kind not in "iu"
            or col.dtype.kind not in "iu"
        ):
            raise CodecError("a sparse matrix needs integer rows and columns, one per value")
        if row.size and (
            row.min() < 0 or row.max() >= shape[0] or col.min() < 0 or col.max() >= shape[1]
        ):
            raise CodecError(f"a sparse matrix's indices lie outside its shape {shape}")
        return shape, row, col, data

    def toarray(self) -> np.ndarray:
        """The dense matrix (duplicate entries summed, as scipy does)."""
        shape, row, col, data = self._checked(LIMITS.max_elements)
        dense = np.zeros(shape, dtype=np.result_type(data.dtype, np.float64))
        np.add.at(dense, (row, col), data)
        return dense

    def tosparse(self):
        """A ``scipy.sparse.csr_matrix`` of the same entries."""
        import scipy.sparse

        shape, row, col, data = self._checked(float(LIMITS.max_elements) ** 2)
        if max(shape) > LIMITS.max_elements:
            raise CodecError(f"a sparse matrix of shape {shape} is too large to read here")
        return scipy.sparse.coo_matrix((data, (row, col)), shape=shape).tocsr()


register_dataclass(SparseMatrix)


# --- the unpickler -------------------------------------------------------------------------


class _Pickler(pickle.Pickler):
    def reducer_override(self, obj: Any) -> Any:
        # numpy pickles a non-contiguous array through ndarray.__setstate__,
        # which the decoder refuses; a contiguous copy goes through _frombuffer.
        if type(obj) is np.ndarray and not (obj.flags.c_contiguous or obj.flags.f_contiguous):
            return np.ascontiguousarray(obj).__reduce_ex__(PROTOCOL)
        return NotImplemented


def _without_sparse(value: Any, sparse: Any, depth: int = 0, done: dict | None = None) -> Any:
    """``value`` with each scipy.sparse matrix in it (tuples, lists, dicts) as a SparseMatrix.

    Done before pickling, not in ``reducer_override``: pickle refuses a NEWOBJ reduction
    of one object standing for another. Deeper than MAX_DEPTH nothing is converted (the
    decoder refuses such values anyway). ``done`` maps (id, depth) of each container
    already converted to its result (how deep it is converted depends on the depth), so
    that a value made of shared references (10 lists of the same 10 lists, 8 deep: 1e8
    leaves in a few hundred bytes) costs at most MAX_DEPTH visits per distinct container,
    not one per path to it, and keeps its sharing.
    """
    if sparse.issparse(value):
        return SparseMatrix.of(value)
    if depth >= MAX_DEPTH:
        return value
    kind = type(value)
    if kind not in (tuple, list, dict):
        return value
    done = {} if done is None else done
    key = (id(value), depth)  # ``value`` stays alive (it is part of the value being sent)
    if key in done:
        return done[key]
    if kind is dict:
        items = {k: _without_sparse(v, sparse, depth + 1, done) for k, v in value.items()}
        result = items if any(items[k] is not value[k] for k in value) else value
    else:
        converted = [_without_sparse(v, sparse, depth + 1, done) for v in value]
        changed = any(a is not b for a, b in zip(converted, value, strict=True))
        result = kind(converted) if changed else value
    done[key] = result
    return result


def dumps(value: Any) -> bytes:
    """Pickle ``value`` in the wire format (used by the worker for results)."""
    buffer = io.BytesIO()
    # scipy is looked up, not imported: a result cannot be sparse unless it is loaded
    sparse = sys.modules.get("scipy.sparse")
    if sparse is not None:
        value = _without_sparse(value, sparse)
    _Pickler(buffer, protocol=PROTOCOL).dump(value)
    return buffer.getvalue()


def loads(data: bytes, limits: DecodeLimits | None = None) -> Any:
    """Unpickle worker output, accepting plain data only, within ``limits``.

    Parameters
    ----------
    data : bytes
        A pickle made by :func:`dumps` (or by anything pretending to be it).
    limits : DecodeLimits, optional
        What decoding may cost (default :data:`LIMITS`).

    Returns
    -------
    object
        Numbers, strings, bytes, None, lists, tuples, dicts, sets, numpy
        arrays and scalars of plain dtypes and registered robolab
        dataclasses, within the limits.

    Raises
    ------
    CodecError
        When the data names anything outside the allow-list, holds a dtype
        that is not plain, exceeds a limit, contains itself, or is not a valid
        pickle. The message is one line that can be shown to the student.
    """
    limits = limits or LIMITS
    if len(data) > limits.max_bytes:
        raise CodecError(
            f"the result is too large ({len(data)} bytes; at most {limits.max_bytes} are accepted)"
        )
    # Only a pickle that names a class of robolab.maps or robolab.bag can need one of their
    # dataclasses: each module is imported (robolab.maps imports scipy, robolab.bag rosbags:
    # a quarter of a second) when the decoder first looks up one of its classes
    # (_Dataclasses.get), not for every plain result.
    value = decode(data, limits, _ALLOWED, _DATACLASSES)
    check_plain(value, limits)
    return value


def check_plain(value: Any, limits: DecodeLimits | None = None) -> None:
    """Raise :class:`CodecError` unless ``value`` is plain data within ``limits``."""
    limits = limits or LIMITS
    total = _Walk(limits).weight(value, 0)
    if total > limits.max_elements:
        raise CodecError(
            f"the result is too large: {total} elements counting repeated references "
            f"(at most {limits.max_elements} are accepted)"
        )


class _Walk:
    """One pass over a decoded value: types, depth, cycles, and expanded size (memoized)."""

    def __init__(self, limits: DecodeLimits) -> None:
        self.limits = limits
        self.weights: dict[int, int] = {}
        self.open: set[int] = set()

    def weight(self, value: Any, depth: int) -> int:
        if depth > self.limits.max_depth:
            raise CodecError(
                f"values nested deeper than {self.limits.max_depth} levels are not accepted"
            )
        kind = type(value)
        if kind in _PLAIN_SCALARS:
            return self._scalar(value)
        if kind is np.ndarray or isinstance(value, np.generic):
            plain_dtype(value.dtype)
            return 1 + value.nbytes // 8
        if kind is range:
            return 1 + len(value)
        key = id(value)
        known = self.weights.get(key)
        if known is not None:
            return known
        if key in self.open:
            raise CodecError("a value that contains itself is not accepted")
        self.open.add(key)
        total = 1
        for item in self._children(value, kind):
            total += self.weight(item, depth + 1)
            if total > self.limits.max_elements:
                break  # already too large; the caller reports it
        self.open.discard(key)
        self.weights[key] = total
        return total

    def _scalar(self, value: Any) -> int:
        kind = type(value)
        if kind is int:
            check_int(value, self.limits)
            return 1 + value.bit_length() // 64
        if kind is fractions.Fraction:
            check_int(value.numerator, self.limits)
            check_int(value.denominator, self.limits)
            return 2
        if kind is str and len(value) > self.limits.max_text:
            raise CodecError(
                f"a string of {len(value)} characters is too long "
                f"(at most {self.limits.max_text} are accepted)"
            )
        if kind in (str, bytes, bytearray):
            return 1 + len(value) // 8
        return 1

    @staticmethod
    def _children(value: Any, kind: type) -> Any:
        if kind in _CONTAINERS:
            return value
        if kind is dict:
            return (x for pair in value.items() for x in pair)
        if kind is slice:
            return (value.start, value.stop, value.step)
        if _registered(kind):
            fields = dataclasses.fields(value)
            extra = (
                set(vars(value)) - {f.name for f in fields} if hasattr(value, "__dict__") else ()
            )
            missing = [f.name for f in fields if not hasattr(value, f.name)]
            if extra or missing:
                raise CodecError(
                    f"a {kind.__qualname__} with attributes {sorted(extra) or missing} "
                    "beyond or short of its fields is not accepted"
                )
            return [getattr(value, f.name) for f in fields]
        raise CodecError(f"a value of type {kind.__module__}.{kind.__qualname__} is not accepted")
