"""Requests to the worker: arrays out of band, and a large array sent again named by its slot.

Unit tests of :mod:`robolab.grading.wire.arrays` (frames parsed as the worker parses them),
then the same through a real worker: a call sees exactly the grader's array every time,
whatever an earlier call did to its own copy, and a change on the grader's side is sent.
"""

from __future__ import annotations

import numpy as np
import pytest

from robolab.grading.isolation.worker import _read_exactly, read_frame
from robolab.grading.running.proxy import open_submission
from robolab.grading.wire import arrays
from tests.grading import TEST_LIMITS, write_notebook


def _through_pipe(message, sent, received):
    """``message`` encoded by the grader's side and read back by the worker's own reader."""
    import os
    import threading

    r, w = os.pipe()
    views = arrays.encode(message, sent)
    size = sum(v.nbytes for v in views)
    writer = threading.Thread(target=lambda: [os.write(w, bytes(v)) for v in views])
    writer.start()
    try:
        frame = read_frame(r)
    finally:
        writer.join()
        os.close(w)
    assert _read_exactly(r, 1) is None  # nothing left behind: one frame, read whole
    os.close(r)
    body, buffers, slotted = frame
    return size, arrays.decode(body, buffers, received, slotted)


def _big(seed=0, shape=(300, 200)):
    return np.random.default_rng(seed).random(shape)


def test_a_large_array_crosses_once_and_arrives_equal_every_time():
    sent, received = arrays.SentArrays(), arrays.ReceivedArrays()
    field = {"distance": _big(1), "likelihood": _big(2), "resolution": 0.05}
    sizes = []
    for _ in range(4):
        size, got = _through_pipe(("call", field), sent, received)
        sizes.append(size)
        for key in ("distance", "likelihood"):
            assert np.array_equal(got[1][key], field[key]) and got[1][key].flags.writeable
            got[1][key][:] = -1.0  # the call's own copy: the next call must not see it
    # First sight whole, second stored in a slot (still whole), then named by its slot only.
    assert sizes[0] > 2 * field["distance"].nbytes and sizes[1] > 2 * field["distance"].nbytes
    assert sizes[2] < 1000 and sizes[3] < 1000


def test_a_changed_array_is_sent_again():
    sent, received = arrays.SentArrays(), arrays.ReceivedArrays()
    a = _big(3)
    for _ in range(3):
        _through_pipe((a,), sent, received)
    a[17, 3] = np.nextafter(a[17, 3], 2.0)  # one ulp, in place: same object, new content
    size, got = _through_pipe((a,), sent, received)
    assert size > a.nbytes and np.array_equal(got[0], a)
    b = a.copy()  # another object with the same bytes: named by the slot (content, not identity)
    for _ in range(2):
        _through_pipe((a,), sent, received)
    size, got = _through_pipe((b,), sent, received)
    assert size < 1000 and np.array_equal(got[0], b)


def test_identity_layout_and_read_only_survive():
    sent, received = arrays.SentArrays(), arrays.ReceivedArrays()
    f = np.asfortranarray(_big(4))
    ro = _big(5)
    ro.setflags(write=False)
    small = np.arange(5.0)
    for _ in range(4):
        _, (a, b, c, d, e, s) = _through_pipe((f, f, ro, ro, {"f": f}, small), sent, received)
        assert a is b and a is e["f"] and c is d
        assert a.flags.f_contiguous and not a.flags.c_contiguous and np.array_equal(a, f)
        assert not c.flags.writeable and np.array_equal(c, ro)
        assert s.flags.writeable and np.array_equal(s, small)


def test_slots_are_bounded_and_reused():
    sent, received = arrays.SentArrays(), arrays.ReceivedArrays()
    many = [_big(10 + i) for i in range(arrays.SLOTS + 3)]
    for _ in range(3):
        for a in many:
            _, got = _through_pipe((a,), sent, received)
            assert np.array_equal(got[0], a)
    assert len(received._slots) <= arrays.SLOTS
    assert sum(s is not None for s in sent._slots) <= arrays.SLOTS


def test_small_odd_and_object_arrays_travel_whole():
    sent = arrays.SentArrays()
    odd = [np.arange(10.0), _big(6)[:, ::2], np.array([None] * 40000, dtype=object)]
    for _ in range(3):
        for a in odd:
            arrays.encode((a,), sent)
    assert all(kept is None for kept in sent._slots)


@pytest.fixture(scope="module")
def big_calls(tmp_path_factory):
    path = write_notebook(
        tmp_path_factory.mktemp("arrays") / "big.ipynb",
        "import numpy as np\n"
        "KEPT = []\n"
        "def total(field, scale):\n"
        "    s = (float(field['distance'].sum()) * scale, float(field['likelihood'].sum()))\n"
        "    field['distance'][:] = 0.0  # changes its own copy, in place\n"
        "    KEPT.append(field['likelihood'])\n"
        "    return s\n"
        "def later():\n"
        "    for kept in KEPT:  # changes the earlier calls' copies after those calls\n"
        "        kept[:] = 7.0\n"
        "    return len(KEPT)\n",
        lab=None,
    )
    with open_submission(path, limits=TEST_LIMITS) as lab:
        yield lab


def test_through_the_worker_each_call_gets_the_graders_bytes(big_calls):
    field = {"distance": _big(20), "likelihood": _big(21)}
    for step in range(5):
        expected = (float(field["distance"].sum()) * 2, float(field["likelihood"].sum()))
        assert big_calls.total(field, 2) == expected
        # The in-place change is replayed on the grader's array (as in-process): sent again.
        assert not field["distance"].any()
        field["distance"][:] = _big(30 + step)
        assert big_calls.later() == step + 1
        assert np.array_equal(field["likelihood"], _big(21))
