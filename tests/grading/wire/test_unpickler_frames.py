"""The decoder reads the message in memory: frames are skipped, a truncated array is refused."""

from __future__ import annotations

import pickle
import struct

import numpy as np
import pytest

from robolab.grading.wire import codec


def test_a_framed_message_decodes_as_the_standard_unpickler_does():
    value = {"a": [1, 2.5, "x" * 300], "b": (None, True), "c": np.arange(12.0).reshape(3, 4)}
    data = codec.dumps(value)
    assert data[2:3] == pickle.FRAME  # the codec's pickles are framed (protocol 5)
    got = codec.loads(data)
    assert got["a"] == value["a"] and got["b"] == value["b"]
    np.testing.assert_array_equal(got["c"], value["c"])


def test_a_frame_claiming_more_than_the_message_is_refused():
    data = bytearray(codec.dumps([1, 2, 3]))
    data[3:11] = struct.pack("<Q", 1 << 40)
    with pytest.raises(codec.CodecError, match="frame"):
        codec.loads(bytes(data))


def test_a_truncated_array_is_refused():
    data = codec.dumps(np.arange(1000.0))
    for cut in (len(data) // 2, len(data) - 3):
        with pytest.raises(codec.CodecError):
            codec.loads(data[:cut])
