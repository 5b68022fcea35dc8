"""Decoding a hostile result is refused before it costs the grader memory or time.

Each attack of issue 16 is built as the bytes a worker could send. Bounds are
asserted as counts (bytes allocated while decoding, measured with
tracemalloc), never as milliseconds.
"""

from __future__ import annotations

import fractions
import pickle
import random
import re
import struct
import sys
import time
import tracemalloc

import numpy as np
import pytest
from numpy._core.numeric import _frombuffer

from robolab.grading.wire import codec
from robolab.grading.wire.codec import CodecError, DecodeLimits

#: Bytes the grader may allocate while refusing a hostile message, beyond three copies of it
#: (the decoder's stack holds at most ``max_ops`` references: 2 MiB).
DECODE_BYTES = 16 * 2**20


class Reduce:
    """Pickles as ``function(*args)``, then BUILD with ``state``: any stream a worker can write."""

    def __init__(self, function, args, state=None):
        self.function, self.args, self.state = function, args, state

    def __reduce__(self):
        if self.state is None:
            return (self.function, self.args)
        return (self.function, self.args, self.state)


def refused(data: bytes, match: str, limits: DecodeLimits | None = None) -> CodecError:
    """Decode ``data`` expecting a refusal matching ``match``, allocating little on the way."""
    tracemalloc.start()
    try:
        with pytest.raises(CodecError, match=match) as info:
            codec.loads(data, limits)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < DECODE_BYTES + 3 * len(data), f"decoding allocated {peak} bytes"
    assert "\n" not in str(info.value), "the refusal must be one line of feedback"
    return info.value


# --- dtypes ------------------------------------------------------------------------------------


def _structured_state(offset: int) -> tuple:
    state = list(np.dtype([("a", "f8")]).__reduce__()[2])
    state[4] = {"a": (np.dtype("f8"), offset)}
    return tuple(state)


@pytest.mark.parametrize("offset", [8, 4096, 2**40])
def test_a_structured_dtype_with_a_field_outside_the_item_is_refused(offset):
    # Read past its buffer, the field would show grader memory (or crash it, for 2**40).
    for name in ("V8", "f8"):
        dtype = Reduce(np.dtype, (name, False, True), _structured_state(offset))
        data = pickle.dumps(Reduce(_frombuffer, (bytearray(8), dtype, (1,), "C")), protocol=5)
        refused(data, "dtype")


@pytest.mark.parametrize(
    "dtype",
    [
        np.dtype([("a", "i4"), ("b", "f8")]),
        np.dtype([("a", "f8", (2,))]),  # a subarray field
        np.dtype("O"),
        np.dtype("V4"),
        np.dtype("M8[s]"),
        np.dtype("m8[s]"),
        np.dtype(">f8"),
        np.dtype([("a", "i4")], align=True),
    ],
    ids=str,
)
def test_arrays_of_dtypes_that_are_not_plain_are_refused(dtype):
    array = np.zeros(2, dtype=dtype)
    for protocol in (2, 5):
        refused(pickle.dumps(array, protocol=protocol), "dtype|not plain|not accepted")
    refused(pickle.dumps(dtype, protocol=5), "dtype|not accepted")


@pytest.mark.parametrize(
    "state",
    [
        (3, ">", None, None, None, -1, -1, 0),
        (3, "<", None, None, None, 16, -1, 0),  # another item size
        (3, "<", None, ("a",), {"a": (np.dtype("f8"), 0)}, 8, 1, 16),
        (4, "<", None, None, None, -1, -1, 0, {"m": 1}),  # metadata
        "not a state",
    ],
)
def test_a_dtype_state_other_than_its_own_is_refused(state):
    # numpy would apply it through dtype.__setstate__; the decoder never calls it.
    dtype = Reduce(np.dtype, ("f8", False, True), state)
    refused(
        pickle.dumps(Reduce(_frombuffer, (bytearray(8), dtype, (1,), "C")), protocol=5), "dtype"
    )


def test_the_float64_dtype_is_unchanged_after_a_refused_state():
    dtype = Reduce(np.dtype, ("f8", False, True), (3, ">", None, None, None, -1, -1, 0))
    refused(pickle.dumps(dtype, protocol=5), "dtype")
    assert np.dtype("f8").isnative and np.zeros(1).dtype.byteorder in "=<"


@pytest.mark.parametrize(
    "args",
    [
        (bytearray(8), "shape", (1,), "C"),
        (b"\0" * 8, np.dtype("f8"), (2,), "C"),  # shape larger than the data
        (b"\0" * 8, np.dtype("f8"), (1,), "K"),
        ([0.0], np.dtype("f8"), (1,), "C"),
        (b"\0" * 8, np.dtype("f8"), (-1,), "C"),
    ],
)
def test_an_array_whose_parts_do_not_fit_is_refused(args):
    refused(pickle.dumps(Reduce(_frombuffer, args), protocol=5), "array|dtype")


# --- sizes -------------------------------------------------------------------------------------


def test_a_huge_range_is_refused_before_anything_is_built():
    refused(codec.dumps(range(30_000_000)), "range")
    assert codec.loads(codec.dumps(range(1000))) == range(1000)


def _nested(leaf, width: int, depth: int):
    for _ in range(depth):
        leaf = [leaf] * width
    return leaf


def test_nested_shared_references_count_every_leaf():
    data = codec.dumps(_nested(1.0, 10, 8))  # 1e8 leaves in a message of a few hundred bytes
    assert len(data) < 1000
    error = refused(data, "too large")
    assert "repeated references" in str(error)
    # The same shape within the budget decodes (1e4 leaves).
    assert np.asarray(codec.loads(codec.dumps(_nested(1.0, 10, 4)))).shape == (10,) * 4


def test_one_array_referenced_many_times_counts_each_time():
    big = np.zeros(2**20)  # 8 MiB once, 800 MiB if a test stacks the list
    refused(codec.dumps([big] * 100), "too large")
    assert len(codec.loads(codec.dumps([big] * 4))) == 4


def test_tuple_keys_are_not_hashed_beyond_the_budget():
    # hash() of nested tuples walks every shared reference: 1e8 steps for this key.
    key = 1
    for _ in range(8):
        key = (key,) * 10
    refused(codec.dumps({key: 1}), "hash")
    refused(pickle.dumps(Reduce(frozenset, ([key],)), protocol=5), "hash")


def test_keys_with_one_hash_are_refused():
    # Equal hashes make every insertion compare with all earlier keys: quadratic.
    modulus = sys.hash_info.modulus
    keys = [i * modulus for i in range(1, 1000)]
    assert len({hash(k) for k in keys}) == 1
    refused(codec.dumps(dict.fromkeys(keys, 0)), "share one hash")
    refused(codec.dumps(set(keys)), "share one hash")
    assert codec.loads(codec.dumps({-1: "a", -2: "b"})) == {
        -1: "a",
        -2: "b",
    }  # hash(-1) == hash(-2)


@pytest.mark.parametrize("bits", [2**17, 2**21])
def test_huge_integers_and_fractions_are_refused(bits):
    n = (1 << bits) + 1
    refused(codec.dumps(n), "bits")
    refused(pickle.dumps(Reduce(fractions.Fraction, (n, n + 2)), protocol=5), "bits")
    text = "1" + "0" * 5000 + "/3"  # more digits than the 3.10/3.11 form may have
    refused(pickle.dumps(Reduce(fractions.Fraction, (text,)), protocol=5), "Fraction")
    refused(codec.dumps([0, {"k": (n,)}]), "bits")


def test_fractions_of_exact_probabilities_still_decode():
    exact = fractions.Fraction(3, 7) ** 300  # ~1700-bit numerator and denominator
    assert codec.loads(codec.dumps(exact)) == exact


def test_long_strings_are_refused():
    refused(codec.dumps("x" * (codec.LIMITS.max_text + 1)), "characters")
    assert codec.loads(codec.dumps("é" * 1000)) == "é" * 1000


def test_a_message_larger_than_the_limit_is_refused_unread():
    data = codec.dumps(b"x" * 5000)
    refused(data, "too large", DecodeLimits(max_bytes=4096))
    assert codec.loads(data, DecodeLimits(max_bytes=8192)) == b"x" * 5000


@pytest.mark.parametrize("opcode", [pickle.BYTEARRAY8, pickle.BINBYTES8, pickle.BINUNICODE8])
def test_a_buffer_longer_than_its_message_is_never_allocated(opcode):
    data = b"\x80\x05" + opcode + struct.pack("<Q", 2**40) + b"."
    refused(data, "claims")


def test_the_number_of_decoding_steps_is_bounded():
    # One-byte opcodes, more than max_ops of them: the pure-Python decoder stops there.
    assert codec.LIMITS.max_ops <= 2**18
    data = b"\x80\x05(" + b"N" * (codec.LIMITS.max_ops + 10) + b"l."
    refused(data, "steps")
    limits = DecodeLimits(max_ops=100)
    refused(codec.dumps(list(range(200))), "steps", limits)


@pytest.mark.parametrize(
    "data",
    [
        pickle.dumps(Reduce(bytearray, (2**40,)), protocol=5),  # bytearray(n) would allocate n
        pickle.dumps(Reduce(complex, ("1e5",)), protocol=5),
        pickle.dumps(Reduce(range, (0, 2**80)), protocol=5),
        pickle.dumps(Reduce(set, ("abc",)), protocol=5),
    ],
)
def test_allowed_constructors_check_their_arguments_first(data):
    refused(data, "must be|range")


def test_items_cannot_be_added_to_values_that_are_not_containers():
    # APPENDS onto a bytearray, SETITEMS onto an array: only list, dict and set take items.
    data = b"\x80\x05" + pickle.dumps(bytearray(b"a"), protocol=5)[2:-1] + b"(K\x01e."
    refused(data, "adding items")


def test_opcodes_plain_data_never_uses_are_refused():
    refused(b"\x80\x02cbuiltins\nset\n)\x81.", "creating")  # NEWOBJ on set
    refused(b"\x80\x05\x82\x01.", "opcode")  # EXT1


# --- what must still decode -----------------------------------------------------------------------


@pytest.mark.parametrize(
    "value",
    [
        {
            "poses": np.zeros((100, 3)),
            "weights": np.full(100, 0.01),
            "seen": np.zeros(5, dtype=bool),
            "count": np.int64(3),
        },
        (np.eye(3), 0.5, [np.arange(3)] * 3),
        [(1.0, 2.0, 0.1)] * 1000,
        {"observation": (1, True, "cell 3", [2, (4, 5)])},
        {(0, 1): 1.0, (1, 0): fractions.Fraction(1, 3), frozenset({1}): None},
        np.float32(1.5),
        np.bool_(False),
        np.array(["north", "east"]),
    ],
)
def test_plain_results_decode_unchanged(value):
    got = codec.loads(codec.dumps(value))
    assert pickle.dumps(got, protocol=5) == pickle.dumps(value, protocol=5)


def test_results_near_the_limits_still_decode():
    array = np.ones(2**21)  # 16 MiB, three times
    got = codec.loads(codec.dumps([array, array, array]))
    assert got[0].shape == (2**21,) and got[0].dtype == np.float64


def test_every_robolab_dataclass_round_trips_and_stays_checked():
    from robolab.maps import OccupancyGrid

    grid = OccupancyGrid(np.zeros((3, 4)), 0.5, (1.0, 2.0, 0.0))
    got = codec.loads(codec.dumps([grid, grid]))
    assert got[0] is got[1] and type(got[0]) is OccupancyGrid
    # A dataclass rebuilt without its fields, or with an attribute too many, is refused.
    empty = b"\x80\x05\x8c\x0crobolab.maps\x8c\rOccupancyGrid\x93)\x81."  # NEWOBJ, no BUILD
    refused(empty, "without its fields")
    hollow = pickle.dumps(grid, protocol=5).replace(b"resolution", b"resolutiom")
    refused(hollow, "fields")


# --- work that grows faster than the message (issue 25) -------------------------------------------
#
# The stream can name one object again and again through the memo (BINGET costs 2 bytes), so
# any operation whose cost depends on the size of its arguments -- the gcd normalising a
# Fraction, parsing its decimal text, hashing a key, copying a buffer -- could cost the grader
# far more than the message's size. Work is measured as CPU time relative to decoding a plain
# message of the same size in the same run (never as absolute time), and as the unpickler's
# deterministic work count.

#: Most CPU time a message may cost, as a multiple of decoding a plain message of its size.
#: Hashing keys costs 10-12x (measured 2026-12-03, idle: the plain message got faster when
#: the unpickler stopped copying frames, which raised every ratio); 12 failed a run under load.
#: The work this guards against grows with the stream's memo references: 100x and more.
#: The exact bound is the deterministic work count (the next test).
CPU_RATIO = 20


def _odd(bits: int, seed: int) -> int:
    return random.Random(seed).getrandbits(bits) | 1 | (1 << (bits - 1))


def _fraction_bombs(copies: int) -> bytes:
    args = (_odd(2**16 - 1, 1), _odd(2**16 - 1, 2))  # one tuple: the pickle refers back to it
    return pickle.dumps([Reduce(fractions.Fraction, args) for _ in range(copies)], protocol=5)


def _fraction_text_bombs(copies: int) -> bytes:
    args = (f"{_odd(14_000, 3)}/{_odd(14_000, 4)}",)  # 4215 digits each, within the text form
    return pickle.dumps([Reduce(fractions.Fraction, args) for _ in range(copies)], protocol=5)


def _hash_bombs(copies: int) -> bytes:
    key = (_odd(2**16 - 1, 5),) * 8  # hash() of a tuple is not cached: the int is read 8 times
    return pickle.dumps([{key: i} for i in range(copies)], protocol=5)


def _fraction_key_bombs(copies: int) -> bytes:
    key = fractions.Fraction(_odd(2**16 - 1, 6), 3**40)  # its hash is a modular inverse
    return pickle.dumps([{key: i} for i in range(copies)], protocol=5)


def _frozenset_bombs(copies: int) -> bytes:
    key = 1
    for _ in range(5):
        key = (key,) * 10  # 1e5 leaves, a few hundred bytes
    args = ([key],)
    return pickle.dumps([Reduce(frozenset, args) for _ in range(copies)], protocol=5)


def _bytearray_bombs(copies: int) -> bytes:
    args = (b"x" * 2**20,)
    return pickle.dumps([Reduce(bytearray, args) for _ in range(copies)], protocol=5)


def _deep_bombs(copies: int) -> bytes:
    deep = _nested(1.0, 1, codec.MAX_DEPTH - 2)
    return codec.dumps([deep] * copies)


BOMBS = {
    "fractions": _fraction_bombs,
    "fraction-text": _fraction_text_bombs,
    "tuple-keys": _hash_bombs,
    "fraction-keys": _fraction_key_bombs,
    "frozensets": _frozenset_bombs,
    "bytearrays": _bytearray_bombs,
    "deep-lists": _deep_bombs,
}


def _cpu(data: bytes) -> float:
    """Least CPU time of three decodes of ``data`` (accepted or refused)."""
    best = float("inf")
    for _ in range(3):
        start = time.thread_time()
        try:
            codec.loads(data)
        except CodecError:
            pass
        best = min(best, time.thread_time() - start)
    return best


def _plain(size: int) -> bytes:
    """A plain message of floats of about ``size`` bytes (9 bytes a float)."""
    return codec.dumps([float(i) for i in range(max(size // 9, 1))])


@pytest.mark.parametrize("name", BOMBS)
def test_decoding_costs_a_small_multiple_of_a_plain_message_of_the_same_size(name):
    data = BOMBS[name](2000)
    baseline = _cpu(_plain(len(data)))
    cost = _cpu(data)
    assert cost <= CPU_RATIO * baseline, (
        f"{name}: {len(data)} bytes took {cost / baseline:.0f} times a plain message's CPU"
    )


@pytest.mark.parametrize("name", BOMBS)
def test_the_work_counted_is_within_the_messages_budget(name, monkeypatch):
    # Deterministic: the decoder counts the work it does beyond reading, and the count
    # never exceeds base + per-byte budget, however many times an object is referred to.
    from robolab.grading.wire import unpickler

    seen = []
    real = unpickler.Unpickler.load

    def load(self):
        try:
            return real(self)
        finally:
            seen.append((self.work, self.work_budget, self.size))

    monkeypatch.setattr(unpickler.Unpickler, "load", load)
    for copies in (1, 10, 1000):
        try:
            codec.loads(BOMBS[name](copies))
        except CodecError as error:
            assert re.search("cost more work|nested deeper|more bytes than", str(error))
    for work, budget, size in seen:
        assert budget == codec.LIMITS.base_work + codec.LIMITS.work_per_byte * size
        # The last charge may pass the budget once (it is refused before it runs).
        assert work <= budget + (2**16 // 64 + 1) ** 2


@pytest.mark.parametrize("name", ["fractions", "fraction-text", "tuple-keys", "bytearrays"])
def test_many_references_to_one_costly_object_are_refused(name):
    error = refused(BOMBS[name](2000), "cost more work|more bytes than its message")
    assert "\n" not in str(error)


def test_one_costly_object_in_its_own_bytes_still_decodes():
    # A single big Fraction pays for its gcd with its own bytes; so do distinct ones.
    big = fractions.Fraction(_odd(2**16 - 1, 7), _odd(2**16 - 1, 8))
    assert codec.loads(codec.dumps(big)) == big
    exact = [fractions.Fraction(3, 7) ** k for k in range(1, 300)]
    assert codec.loads(codec.dumps(exact)) == exact
    keys = {(i, i + 1, (i, "cell")): fractions.Fraction(i, 7) for i in range(10_000)}
    assert codec.loads(codec.dumps(keys)) == keys


def test_decoding_is_charged_to_the_call_that_sent_the_result(tmp_path, monkeypatch):
    # The grader's CPU spent decoding counts against the call's CPU budget: a clock that
    # says each decode took 5 s turns a cheap call into a timeout naming the decoding.
    from dataclasses import replace

    from robolab.grading.running import channel, proxy
    from tests.grading import TEST_LIMITS, write_notebook

    path = write_notebook(tmp_path / "sub.ipynb", "def half(x):\n    return x / 2\n")
    limits = replace(TEST_LIMITS, cpu_seconds=1, total_cpu_seconds=100)  # the call's limit binds
    with proxy.open_submission(path, limits=limits) as sub:
        assert sub.half(3.0) == 1.5
        ticks = iter(range(0, 1000, 5))
        monkeypatch.setattr(channel, "decode_clock", lambda: float(next(ticks)))
        with pytest.raises(proxy.WorkerTimeout, match="decoding its result: 5.0 s"):
            sub.half(3.0)


def test_shared_references_cost_the_sender_one_visit_each_with_scipy_loaded(monkeypatch):
    """With scipy.sparse loaded, dumps looks for sparse matrices inside the value: once
    per distinct container and depth (it walked every path: 1e8 leaves, minutes of CPU),
    and a sparse matrix under shared references is converted wherever it appears."""
    import scipy.sparse

    looks = []
    issparse = scipy.sparse.issparse
    monkeypatch.setattr(scipy.sparse, "issparse", lambda v: looks.append(1) or issparse(v))
    refused(codec.dumps(_nested(1.0, 10, 8)), "too large")
    assert 0 < len(looks) < 1000  # 9 containers: about 11 looks each (1e8 before)
    matrix = scipy.sparse.eye(3, format="csr")
    inner = [matrix, 1]
    value = [inner, (inner, {"m": inner}), [[inner]]]
    back = codec.loads(codec.dumps(value))
    found = [back[0][0], back[1][0][0], back[1][1]["m"][0], back[2][0][0][0]]
    assert all(isinstance(m, codec.SparseMatrix) for m in found)
    assert all(np.array_equal(m.toarray(), np.eye(3)) for m in found)
