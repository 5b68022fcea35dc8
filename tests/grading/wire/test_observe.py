"""Through the worker, a call changes its arguments and shares memory exactly as in-process.

The oracle is the same function run in this process on copies of the same
arguments: every property a hidden test can look at -- the argument values
after the call, ``result is argument``, ``np.shares_memory`` with each
argument and between results, ``flags.writeable`` -- must be the same through
the worker.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from robolab.grading.running.proxy import open_submission
from robolab.grading.wire.observe import replay
from tests.grading import TEST_LIMITS, write_notebook

FUNCTIONS = """\
import numpy as np

def scale_in_place(a):
    a *= 2.0
    return float(a.sum())

def clip_nested(data):
    data["values"][0][:] = 0.0
    return len(data)

def same(a):
    return a

def row(a, i):
    return a[i]

def every_other(a):
    return a[:, ::2]

def reversed_view(a):
    return a[::-1]

def as_bytes(a):
    return a.view(np.uint8)

def frozen(a):
    out = a + 1.0
    out.setflags(write=False)
    return out

def repeated_rows(a):
    return [a[0], a[0], a[1]]

def shared_result(a):
    out = a * 3.0
    return out, out[1:]

def honest(a, b=None):
    return a + 1.0, {"t": a.T.copy()}

def mutate_kwarg(a, *, out):
    out[...] = a
    return out

def fill_then_fail(a):
    a[:] = -1
    raise ValueError("gave up")
"""

CASES = [
    ("scale_in_place", lambda: (np.arange(6.0),), {}),
    ("clip_nested", lambda: ({"values": [np.ones(3), np.ones(2)]},), {}),
    ("same", lambda: (np.arange(4.0),), {}),
    ("row", lambda: (np.arange(6.0).reshape(2, 3), 1), {}),
    ("every_other", lambda: (np.arange(12.0).reshape(3, 4),), {}),
    ("every_other", lambda: (np.asfortranarray(np.arange(12.0).reshape(3, 4)),), {}),
    ("reversed_view", lambda: (np.arange(5.0),), {}),
    ("as_bytes", lambda: (np.arange(3, dtype=np.int32),), {}),
    ("frozen", lambda: (np.zeros(3),), {}),
    ("repeated_rows", lambda: (np.arange(6.0).reshape(2, 3),), {}),
    ("shared_result", lambda: (np.arange(4.0),), {}),
    ("honest", lambda: (np.arange(6.0).reshape(2, 3),), {}),
    ("mutate_kwarg", lambda: (np.arange(3.0),), {"out": np.zeros(3)}),
]


@pytest.fixture(scope="module")
def sub(tmp_path_factory):
    path = write_notebook(tmp_path_factory.mktemp("observe") / "o.ipynb", FUNCTIONS, lab=None)
    with open_submission(path, limits=TEST_LIMITS) as proxy:
        yield proxy


def _namespace() -> dict:
    ns: dict = {}
    exec(FUNCTIONS, ns)  # noqa: S102 - the test's own functions
    return ns


def _arrays(value, path=()):
    if isinstance(value, np.ndarray):
        yield path, value
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            yield from _arrays(v, (*path, i))
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from _arrays(v, (*path, k))


def _what_a_test_sees(args, kwargs, result) -> dict:
    inputs = list(_arrays((args, kwargs)))
    outputs = list(_arrays(result))
    return {
        "inputs": [(p, a.tolist()) for p, a in inputs],
        "outputs": [(p, r.tolist(), r.flags.writeable) for p, r in outputs],
        "is": [(p, q) for p, r in outputs for q, a in inputs if r is a],
        "shares": [(p, q) for p, r in outputs for q, a in inputs if np.shares_memory(r, a)],
        "between": [
            (p, q)
            for i, (p, r) in enumerate(outputs)
            for q, s in outputs[i + 1 :]
            if np.shares_memory(r, s)
        ],
        "result_is_input": any(result is a for _, a in inputs),
    }


@pytest.mark.parametrize("name, make, kwargs", CASES, ids=[c[0] for c in CASES])
def test_a_call_through_the_worker_looks_like_the_call_in_process(sub, name, make, kwargs):
    local_args, local_kwargs = make(), copy.deepcopy(kwargs)
    expected = _namespace()[name](*local_args, **local_kwargs)
    args, kwargs = make(), copy.deepcopy(kwargs)
    got = getattr(sub, name)(*args, **kwargs)
    assert _what_a_test_sees(args, kwargs, got) == _what_a_test_sees(
        local_args, local_kwargs, expected
    )


def test_changes_made_before_raising_are_replayed(sub):
    a = np.arange(3.0)
    with pytest.raises(ValueError, match="gave up"):
        sub.fill_then_fail(a)
    assert a.tolist() == [-1.0, -1.0, -1.0]


def test_a_view_of_a_non_contiguous_argument_is_approximated(sub):
    # The worker received a contiguous copy; the view cannot be rebuilt exactly,
    # so the result stays a fresh array (documented in docs/grading.md).
    base = np.arange(24.0).reshape(4, 6)[:, ::2]
    got = sub.every_other(base)
    assert got.tolist() == base[:, ::2].tolist() and not np.shares_memory(got, base)


@pytest.mark.parametrize(
    "observation",
    [
        None,
        "junk",
        {"modified": [((("i", 0), ("i", 0)), np.zeros(2))]},  # wrong shape: ignored
        {"modified": [("not a path", np.zeros(3))]},
        {"aliases": [((), "view", ("arg", (("i", 0), ("i", 0))), 8 * 2, (3,), (8,), (8,))]},
        {"aliases": [((), "view", ("arg", (("i", 0), ("i", 0))), -8, (3,), (8,), (8,))]},
        {"aliases": [((), "view", ("arg", (("i", 0), ("i", 0))), 0, (3,), (800,), (8,))]},
        {"aliases": [((), "view", ("arg", (("i", 0), ("i", 0))), 0, (3,), (8,), (16,))]},
        {"aliases": [((), "view", ("arg", (("i", 9),)), 0, (3,), (8,), (8,))]},
        {"aliases": [((), "same", ("arg", (("i", 0), ("i", 1))))]},
        {"readonly": [(("k", "nope"),)]},
    ],
)
def test_a_malformed_or_unsafe_observation_changes_nothing(observation):
    caller = np.arange(4.0)
    decoded = np.array([9.0, 9.0, 9.0])
    got = replay(decoded, observation, (caller,), {})
    assert caller.tolist() == [0.0, 1.0, 2.0, 3.0]
    assert got is decoded and got.flags.writeable and not np.shares_memory(got, caller)


def test_a_view_is_rebuilt_only_over_the_bytes_the_worker_returned():
    caller = np.arange(4.0)
    entry = ((), "view", ("arg", (("i", 0), ("i", 0))), 8, (3,), (8,), (8,))
    good = replay(np.array([1.0, 2.0, 3.0]), {"aliases": [entry]}, (caller,), {})
    assert np.shares_memory(good, caller) and good.tolist() == [1.0, 2.0, 3.0]
    lying = replay(np.array([5.0, 5.0, 5.0]), {"aliases": [entry]}, (caller,), {})
    assert not np.shares_memory(lying, caller)
