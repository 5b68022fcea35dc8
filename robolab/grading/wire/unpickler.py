"""A pure-Python unpickler that runs allowed opcodes only, under a budget the grader sets.

The engine behind :func:`robolab.grading.wire.codec.loads`: the C unpickler cannot
be stopped before it hashes a key, allocates a buffer or calls
``__setstate__``, so every opcode a result may use is run here, checked
first. :class:`Unpickler` knows nothing of what is allowed: the codec passes
its allow-list of constructors and dataclasses, and :class:`DecodeLimits`.
"""

from __future__ import annotations

import dataclasses
import fractions
import io
import pickle
import struct
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["CodecError", "DecodeLimits", "LIMITS", "MAX_DEPTH", "Unpickler", "active", "check_int"]

#: Deepest nesting of containers accepted in a value.
MAX_DEPTH = 64


@dataclasses.dataclass(frozen=True)
class DecodeLimits:
    """What decoding one message may cost the grader.

    Attributes
    ----------
    max_bytes : int
        Largest message.
    max_ops : int
        Most pickle opcodes executed (the decoder is pure Python: this bounds its time).
    max_elements : int
        Largest expanded size of the value: every container, scalar and
        8 bytes of array or text data count one, as often as referenced.
    max_int_bits : int
        Largest integer (and Fraction numerator or denominator), in bits.
    max_text : int
        Longest string, in characters.
    work_per_byte, base_work : int
        Work the decoder may do beyond reading the message, in units of about one
        machine-word operation: ``base_work + work_per_byte * len(message)`` for the
        whole message. Hashing dict keys and set items (their expanded size) and
        normalising Fractions (the gcd is quadratic in their size) are charged,
        wherever the stream refers to an object again through the memo, so a small
        message can never demand much work.
    max_equal_hashes : int
        Most keys of one dict (or items of one set) sharing one hash value.
    max_depth : int
        Deepest nesting of containers.
    """

    max_bytes: int = 64 * 2**20
    max_ops: int = 2**18
    max_elements: int = 2**23
    max_int_bits: int = 2**16
    max_text: int = 2**20
    work_per_byte: int = 64
    base_work: int = 2**16
    max_equal_hashes: int = 8
    max_depth: int = MAX_DEPTH


#: The limits :func:`loads` applies unless given others.
LIMITS = DecodeLimits()


class CodecError(Exception):
    """A value from the worker is not plain data, is too costly, or is not a valid pickle.

    Deliberately not a ValueError: a refused result must fail a hidden test
    that expects ``ValueError``.
    """


_Base = pickle._Unpickler  # the pure-Python unpickler: every opcode is ours to check
_OPS = pickle  # opcode constants
#: Opcodes that only read data or move it on the stack; run as the standard library does.
_PLAIN_OPS = (
    "PROTO FRAME STOP MARK POP POP_MARK DUP NONE NEWFALSE NEWTRUE INT BININT BININT1 BININT2 "
    "LONG LONG1 LONG4 FLOAT BINFLOAT BINBYTES SHORT_BINBYTES BINUNICODE SHORT_BINUNICODE "
    "UNICODE STRING BINSTRING SHORT_BINSTRING EMPTY_TUPLE TUPLE TUPLE1 TUPLE2 TUPLE3 EMPTY_LIST "
    "LIST EMPTY_DICT EMPTY_SET GET BINGET LONG_BINGET PUT BINPUT LONG_BINPUT MEMOIZE GLOBAL "
    "STACK_GLOBAL"
).split()


class Unpickler(_Base):
    """A pure-Python unpickler that runs allowed opcodes only, under a :class:`DecodeLimits`.

    Parameters
    ----------
    data : bytes
        The message.
    limits : DecodeLimits
        What decoding may cost.
    allowed : dict
        ``{(module, name): constructor}``: the only callables the stream may name and call.
    classes : dict
        ``{(module, qualname): dataclass}``: the only classes it may instantiate (NEWOBJ)
        and fill field by field (BUILD).
    """

    dispatch: dict = {getattr(_OPS, n)[0]: _Base.dispatch[getattr(_OPS, n)[0]] for n in _PLAIN_OPS}

    def __init__(
        self,
        data: bytes,
        limits: DecodeLimits,
        allowed: dict[tuple[str, str], Callable[..., Any]],
        classes: dict[tuple[str, str], type],
    ) -> None:
        self._message = io.BytesIO(data)
        super().__init__(self._message)
        self.limits = limits
        self.allowed = allowed
        self.constructors = frozenset(map(id, allowed.values()))
        self.classes = classes
        self.size = len(data)
        self.work = 0
        self.copied = 0  # bytes copied into bytearrays (at most the message's size)
        self.work_budget = limits.base_work + limits.work_per_byte * len(data)
        self.key_weights: dict[int, tuple[Any, int]] = {}
        self.hash_counts: dict[int, tuple[Any, dict[int, int]]] = {}
        self.unbuilt: dict[int, Any] = {}

    def load(self) -> Any:
        # The standard loop, counting opcodes (a pure-Python unpickler must be bounded in steps).
        # The whole message is in memory: opcodes read it directly (FRAME only announces the
        # size of what follows, see load_frame), without the standard library's frame
        # buffer, which cost a Python call per opcode and a second copy of every array.
        self.read, self.readline = self._message.read, self._message.readline
        self.readinto = self._readinto
        self.metastack, self.stack = [], []
        self.append = self.stack.append
        self.proto = 0
        dispatch, read, budget = self.dispatch, self.read, self.limits.max_ops
        try:
            while True:
                key = read(1)
                if not key:
                    raise EOFError
                function = dispatch.get(key[0])
                if function is None:
                    raise CodecError(f"pickle opcode {key!r} is not accepted in a result")
                budget -= 1
                if budget < 0:
                    raise CodecError(
                        f"the result is too complex (more than {self.limits.max_ops} pickle steps)"
                    )
                function(self)
        except pickle._Stop as stop:
            return stop.value

    def find_class(self, module: str, name: str) -> Any:
        allowed = self.allowed.get((module, name))
        if allowed is not None:
            return allowed
        cls = self.classes.get((module, name))
        if cls is not None:
            return cls
        raise CodecError(f"a value of type {module}.{name} is not plain data and is not accepted")

    def _readinto(self, buffer: bytearray) -> int:
        n = self._message.readinto(buffer)
        if n < len(buffer):
            raise CodecError("the result's encoding was truncated")
        return n

    def load_frame(self) -> None:
        # A frame groups the opcodes that follow; read from memory, they need no buffering.
        self._length("<Q", "a frame")

    # -- sizes before allocation --

    def _length(self, fmt: str, what: str) -> int:
        (n,) = struct.unpack(fmt, self.read(struct.calcsize(fmt)))
        if n > self.size:
            raise CodecError(f"{what} claims {n} bytes in a message of {self.size}")
        return n

    def load_bytearray8(self) -> None:
        data = bytearray(self._length("<Q", "a bytearray"))
        self.readinto(data)
        self.append(data)

    def load_binbytes8(self) -> None:
        self.append(self.read(self._length("<Q", "a bytes value")))

    def load_binunicode8(self) -> None:
        self.append(str(self.read(self._length("<Q", "a string")), "utf-8", "surrogatepass"))

    # -- calls --

    def load_reduce(self) -> None:
        args = self.stack.pop()
        function = self.stack[-1]
        if id(function) not in self.constructors or type(args) is not tuple:
            raise CodecError(f"calling {short(function)} is not accepted in a result")
        self.stack[-1] = function(*args)

    def load_newobj(self) -> None:
        args = self.stack.pop()
        cls = self.stack.pop()
        known = isinstance(cls, type) and self.classes.get((cls.__module__, cls.__qualname__))
        if known is not cls or args != ():
            raise CodecError(f"creating {short(cls)} is not accepted in a result")
        obj = cls.__new__(cls)
        self.unbuilt[id(obj)] = obj
        self.append(obj)

    def load_build(self) -> None:
        state = self.stack.pop()
        inst = self.stack[-1]
        if isinstance(inst, np.dtype):
            # Never __setstate__: a dtype's state must be the one it was built with.
            if type(state) is not tuple or state != inst.__reduce__()[2]:
                raise CodecError(f"a numpy dtype with the state {short(state)} is not accepted")
            return
        if self.unbuilt.pop(id(inst), None) is None:
            raise CodecError(f"setting the state of {short(inst)} is not accepted")
        names = {f.name for f in dataclasses.fields(inst)}
        if not (type(state) is dict and set(state) <= names and all(type(k) is str for k in state)):
            raise CodecError(f"{type(inst).__qualname__} must be rebuilt from its fields only")
        inst.__dict__.update(state)

    # -- work under a budget --

    def charge(self, units: int, what: str) -> None:
        """Count ``units`` of work before doing it; CodecError past the message's budget."""
        self.work += units
        if self.work > self.work_budget:
            raise CodecError(
                f"the result's {what} cost more work to decode than a result of "
                f"{self.size} bytes may"
            )

    # -- hashing under a budget --

    def hashed(self, container: set | dict, keys: Any, values: Any = None) -> Any:
        """Add ``keys`` (and ``values``) to ``container`` after checking what hashing them costs."""
        if type(keys) not in (list, tuple):
            raise CodecError("set items must be a list or tuple")
        counts = self.hash_counts.setdefault(id(container), (container, {}))[1]
        for key in keys:
            self.charge(self._key_weight(key, 0), "dict keys or set items (to hash)")
            h = hash(key)
            counts[h] = counts.get(h, 0) + 1
            if counts[h] > self.limits.max_equal_hashes:
                raise CodecError("too many dict keys or set items share one hash value")
        if values is None:
            container.update(keys)
        else:
            container.update(zip(keys, values, strict=True))
        return container

    def _key_weight(self, key: Any, depth: int) -> int:
        kind = type(key)
        if kind is int:
            check_int(key, self.limits)
            return 1 + key.bit_length() // 64
        if kind in (type(None), bool, float, complex, str, bytes, range) or isinstance(
            key, np.generic
        ):
            return 1
        if kind is fractions.Fraction:
            # The numerator's hash and the denominator's modular inverse: twice an int's work.
            return 2 + (key.numerator.bit_length() + key.denominator.bit_length()) // 32
        if kind not in (tuple, frozenset):
            raise CodecError(f"a {kind.__name__} cannot be a dict key or set item in a result")
        known = self.key_weights.get(id(key))
        if known is not None:
            return known[1]
        if depth > self.limits.max_depth:
            raise CodecError(
                f"values nested deeper than {self.limits.max_depth} levels are not accepted"
            )
        weight = 1 + len(key) if kind is frozenset else 1
        if kind is tuple:
            for item in key:
                weight += self._key_weight(item, depth + 1)
                if self.work + weight > self.work_budget:
                    self.charge(weight, "dict keys or set items (to hash)")
        self.key_weights[id(key)] = (key, weight)  # immutable: its weight never changes
        return weight

    def _container(self, kind: type) -> Any:
        target = self.stack[-1]
        if type(target) is not kind:
            raise CodecError(f"adding items to a {type(target).__name__} is not accepted")
        return target

    def load_dict(self) -> None:
        items = self.pop_mark()
        self.append(self.hashed({}, items[0::2], items[1::2]))

    def load_setitem(self) -> None:
        value, key = self.stack.pop(), self.stack.pop()
        self.hashed(self._container(dict), [key], [value])

    def load_setitems(self) -> None:
        items = self.pop_mark()
        self.hashed(self._container(dict), items[0::2], items[1::2])

    def load_additems(self) -> None:
        items = self.pop_mark()
        self.hashed(self._container(set), items)

    def load_frozenset(self) -> None:
        items = self.pop_mark()  # first: it replaces self.append
        self.append(frozenset(self.hashed(set(), items)))

    def load_append(self) -> None:
        value = self.stack.pop()
        self._container(list).append(value)

    def load_appends(self) -> None:
        items = self.pop_mark()
        self._container(list).extend(items)

    def persistent_load(self, pid: Any) -> Any:
        raise CodecError("persistent references are not accepted")


for _name in (
    "FRAME BYTEARRAY8 BINBYTES8 BINUNICODE8 REDUCE NEWOBJ BUILD DICT SETITEM SETITEMS "
    "ADDITEMS FROZENSET APPEND APPENDS"
).split():
    Unpickler.dispatch[getattr(_OPS, _name)[0]] = getattr(Unpickler, f"load_{_name.lower()}")


#: The unpickler decoding on this thread right now (the constructors read its limits).
_current = threading.local()


def active() -> Unpickler:
    """The unpickler decoding on this thread (for constructors that need its limits)."""
    active = getattr(_current, "unpickler", None)
    if active is None:
        raise CodecError("this constructor only runs while a result is decoded")
    return active


def decode(
    data: bytes,
    limits: DecodeLimits,
    allowed: dict[tuple[str, str], Callable[..., Any]],
    classes: dict[tuple[str, str], type],
) -> Any:
    """Unpickle ``data`` with :class:`Unpickler`; every failure becomes a one-line CodecError."""
    unpickler = Unpickler(data, limits, allowed, classes)
    previous, _current.unpickler = getattr(_current, "unpickler", None), unpickler
    try:
        value = unpickler.load()
    except CodecError:
        raise
    except Exception as exc:  # a malformed stream can raise almost anything
        text = " ".join(str(exc).split())[:200]
        raise CodecError(f"not a valid result encoding: {type(exc).__name__}: {text}") from None
    finally:
        _current.unpickler = previous
    if unpickler.unbuilt:
        raise CodecError("a robolab dataclass arrived without its fields")
    return value


def check_int(value: int, limits: DecodeLimits) -> None:
    """CodecError when ``value`` has more bits than ``limits`` allow."""
    if value.bit_length() > limits.max_int_bits:
        raise CodecError(
            f"an integer of {value.bit_length()} bits is too large "
            f"(at most {limits.max_int_bits} bits are accepted)"
        )


def short(value: Any, limit: int = 80) -> str:
    """``repr(value)``, cut to ``limit`` characters (for one-line messages)."""
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a repr that fails is reported by type
        text = f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[:limit] + "..."
