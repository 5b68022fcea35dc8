"""The result codec accepts plain data and refuses anything that could run code in the grader."""

from __future__ import annotations

import fractions
import os
import pickle

import numpy as np
import pytest

from robolab.grading.wire import codec
from robolab.grading.wire.codec import CodecError


@pytest.mark.parametrize(
    "value",
    [
        None,
        True,
        3,
        -(2**70),
        2.5,
        float("nan"),
        1 + 2j,
        "text",
        b"bytes",
        bytearray(b"ba"),
        slice(1, 5, 2),
        range(3),
        [1, [2, 3]],
        (1, "a"),
        {"a": 1, 2: (3.0,)},
        {1, 2},
        frozenset({3}),
        np.float64(1.5),
        np.int32(7),
        np.bool_(True),
        np.complex128(1j),
        fractions.Fraction(3, 4),  # lab 01 returns exact fractions
    ],
)
def test_plain_values_round_trip(value):
    got = codec.loads(codec.dumps(value))
    if isinstance(value, float) and value != value:
        assert got != got
    else:
        assert got == value and type(got) is type(value)


@pytest.mark.parametrize(
    "array",
    [
        np.arange(6.0).reshape(2, 3),
        np.arange(10)[::3],
        np.asfortranarray(np.ones((3, 2))),
        np.zeros((0, 3)),
        np.array(4.0),
        np.array(["a", "bc"]),
        np.array([True, False]),
        np.arange(4, dtype=np.float32),
        np.arange(4, dtype=np.uint8),
        np.array([1 + 2j], dtype=np.complex64),
        np.array([b"ab", b"c"]),
        np.zeros((0, 10**6)),
    ],
)
def test_arrays_round_trip(array):
    got = codec.loads(codec.dumps(array))
    assert type(got) is np.ndarray
    assert got.dtype == array.dtype and got.shape == array.shape
    np.testing.assert_array_equal(got, array)


def test_a_pickle_payload_never_runs(tmp_path):
    marker = tmp_path / "payload-ran"

    class Payload:
        def __reduce__(self):
            return (os.system, (f"touch {marker}",))

    with pytest.raises(CodecError, match="system"):
        codec.loads(pickle.dumps(Payload()))
    assert not marker.exists()


@pytest.mark.parametrize(
    "value",
    [
        np.array([1, "a", None], dtype=object),
        np.array([(1, None)], dtype=[("a", "i4"), ("b", "O")]),
    ],
)
def test_object_arrays_are_refused(value):
    for protocol in (2, 5):
        with pytest.raises(CodecError):
            codec.loads(pickle.dumps(value, protocol=protocol))


class AlwaysEqual:
    def __eq__(self, other):
        return True


@pytest.mark.parametrize(
    "value",
    [
        AlwaysEqual(),
        [1, AlwaysEqual()],
        {"k": AlwaysEqual()},
        eval,
        print,
        np.random.default_rng(0),
        np.ma.masked_array([1.0]),
        np.char.array(["a"]),
    ],
)
def test_non_plain_values_are_refused(value):
    try:
        data = pickle.dumps(value, protocol=5)
    except Exception:
        pytest.skip("not picklable in the first place")
    with pytest.raises(CodecError):
        codec.loads(data)


def test_refusal_is_not_a_value_error():
    # A refused result must fail `pytest.raises(ValueError)` in a hidden test.
    assert not issubclass(CodecError, ValueError)


@pytest.mark.parametrize("data", [b"", b"garbage", pickle.dumps([1, 2])[:-3]])
def test_malformed_streams_are_refused(data):
    with pytest.raises(CodecError, match="not a valid result"):
        codec.loads(data)


def test_deep_nesting_is_refused():
    value: list = []
    for _ in range(codec.MAX_DEPTH + 5):
        value = [value]
    with pytest.raises(CodecError, match="deeper"):
        codec.loads(codec.dumps(value))


def test_values_that_contain_themselves_are_refused():
    # A hidden test comparing or converting one would recurse without end.
    value: list = [1]
    value.append(value)
    with pytest.raises(CodecError, match="contains itself"):
        codec.loads(codec.dumps(value))


def test_shared_references_that_are_not_cycles_are_accepted():
    leaf = [1.0, 2.0]
    got = codec.loads(codec.dumps([leaf, leaf, (leaf,)]))
    assert got == [[1.0, 2.0], [1.0, 2.0], ([1.0, 2.0],)] and got[0] is got[1] is got[2][0]


def test_registered_robolab_dataclass_round_trips():
    from robolab.maps import OccupancyGrid

    assert OccupancyGrid in codec.registered_dataclasses()
    grid = OccupancyGrid(np.zeros((3, 4)), 0.5, (1.0, 2.0, 0.0))
    got = codec.loads(codec.dumps(grid))
    assert type(got) is OccupancyGrid
    np.testing.assert_array_equal(got.data, grid.data)


def test_a_registered_dataclass_carrying_a_non_plain_value_is_refused():
    from robolab.maps import OccupancyGrid

    grid = OccupancyGrid(np.zeros((3, 4)), 0.5, (1.0, 2.0, 0.0))
    object.__setattr__(grid, "smuggled", np.array([None], dtype=object))
    with pytest.raises(CodecError):
        codec.loads(pickle.dumps(grid, protocol=5))


def test_only_robolab_dataclasses_can_be_registered():
    import dataclasses

    @dataclasses.dataclass
    class Foreign:
        x: int

    with pytest.raises(TypeError, match="robolab"):
        codec.register_dataclass(Foreign)
    with pytest.raises(TypeError, match="dataclass"):
        codec.register_dataclass(AlwaysEqual)


class _FractionFrom:
    """Pickles as Fraction(*args), whatever this Python's own Fraction pickles as."""

    def __init__(self, *args):
        self.args = args

    def __reduce__(self):
        return (fractions.Fraction, self.args)


@pytest.mark.parametrize("args", [(-7, 3), ("-7/3",)])
def test_a_fraction_is_rebuilt_from_its_two_pickled_forms(args):
    # Python 3.12+ pickles Fraction(n, d); 3.10 and 3.11 pickle Fraction("n/d").
    got = codec.loads(pickle.dumps(_FractionFrom(*args)))
    assert got == fractions.Fraction(-7, 3) and type(got) is fractions.Fraction


@pytest.mark.parametrize("args", [("1e400",), ("0.5",), (" 1/2",), (1.5, 2), ("1/2", 3)])
def test_a_fraction_from_anything_else_is_refused(args):
    # The constructor's float, Decimal and scientific-notation paths are never reached.
    with pytest.raises(CodecError):
        codec.loads(pickle.dumps(_FractionFrom(*args)))


def test_a_scipy_sparse_result_crosses_as_its_triplets():
    """CSR, CSC and COO matrices (in tuples, lists, dicts) arrive as SparseMatrix, same entries."""
    import scipy.sparse

    dense = np.array([[4.0, 0.0, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 2.5]])
    coo = scipy.sparse.coo_matrix(([1.0, 3.0], ([0, 0], [0, 0])), shape=(3, 3))  # duplicates summed
    value = (
        scipy.sparse.csr_matrix(dense),
        {"H": [scipy.sparse.csc_matrix(dense)]},
        coo,
        np.ones(2),
    )
    got = codec.loads(codec.dumps(value))
    for h in (got[0], got[1]["H"][0]):
        assert isinstance(h, codec.SparseMatrix), f"expected a SparseMatrix, got {type(h)}"
        np.testing.assert_array_equal(h.toarray(), dense, err_msg="the dense matrix must survive")
        assert (h.tosparse() != scipy.sparse.csr_matrix(dense)).nnz == 0
    assert got[0].format == "csr" and got[1]["H"][0].format == "csc"
    np.testing.assert_array_equal(got[2].toarray(), [[4, 0, 0], [0, 0, 0], [0, 0, 0]])
    np.testing.assert_array_equal(got[3], np.ones(2))


@pytest.mark.parametrize(
    "fields",
    [
        {"row": np.array([0, 3])},  # outside the shape
        {"col": np.array([-1, 0])},  # a negative index would wrap around
        {"shape": (2**40, 2**40)},  # a tiny message promising a huge matrix
        {"shape": (3, -1)},
        {"row": np.array([0.0, 1.0])},
        {"data": np.ones(3)},  # not one value per index
    ],
)
def test_a_sparse_matrix_with_bad_triplets_is_refused_when_read(fields):
    """A worker's triplets are checked before the grader builds anything from them."""
    good = {
        "shape": (3, 3),
        "row": np.array([0, 1]),
        "col": np.array([1, 2]),
        "data": np.ones(2),
        "format": "csr",
    }
    bad = codec.loads(codec.dumps(codec.SparseMatrix(**(good | fields))))
    for read in (bad.toarray, bad.tosparse):
        with pytest.raises(CodecError):
            read()


def test_a_pose_graph_round_trips():
    """robolab.datasets.PoseGraph (lab 09's results) is a registered dataclass."""
    from robolab.datasets import PoseGraph

    g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]], [np.eye(3)])
    got = codec.loads(codec.dumps((g, {"objective": np.ones(2)})))[0]
    assert isinstance(got, PoseGraph)
    np.testing.assert_array_equal(got.edges, g.edges)
    np.testing.assert_array_equal(got.information, g.information)
