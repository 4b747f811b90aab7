"""The event container, run splitting and the lossless-transport checksum, by hand."""

from __future__ import annotations

import hashlib
import struct

import numpy as np

from hrn_vo_ros.core.events.arrays import EventArray, EventChecksum, runs


def test_empty_array_has_no_events_in_every_field_and_the_event_dtypes() -> None:
    e = EventArray.empty()
    assert len(e) == 0
    assert [a.shape for a in (e.t, e.x, e.y, e.p)] == [(0,)] * 4
    assert [a.dtype for a in (e.t, e.x, e.y, e.p)] == [np.int64, np.uint16, np.uint16, np.uint8]
    joined = EventArray.concatenate([e, EventArray.from_arrays(np.array([5]), np.array([1]),
                                                               np.array([2]), np.array([1]))])
    assert (joined.t.tolist(), joined.x.tolist(), joined.y.tolist(), joined.p.tolist()) \
        == ([5], [1], [2], [1])
    assert len(EventArray.concatenate([])) == 0


def test_runs_of_equal_keys_by_hand() -> None:
    assert runs(np.array([], np.int64)) == []
    assert runs(np.array([7])) == [(0, 1)]
    assert runs(np.array([3, 3, 3])) == [(0, 3)]
    assert runs(np.array([0, 0, 1, 2, 2, 2, 5])) == [(0, 2), (2, 3), (3, 6), (6, 7)]


def test_checksum_is_sha256_of_the_packed_records_whatever_the_batches() -> None:
    """Each event packs as int64 t, uint16 x, uint16 y, uint8 p (little-endian, 13 bytes);
    the digest is SHA-256 of their concatenation, however the stream is split."""
    t, x, y, p = [10, 10, 25], [1, 300, 2], [4, 5, 65535], [1, 0, 1]
    want = hashlib.sha256(b''.join(
        struct.pack('<qHHB', *ev) for ev in zip(t, x, y, p, strict=True)))
    ev = EventArray.from_arrays(np.array(t), np.array(x), np.array(y), np.array(p))
    for cuts in ([3], [0, 3], [1, 3], [2, 3], [1, 2, 3]):
        c, start = EventChecksum(), 0
        for end in cuts:
            c.update(ev[start:end])
            start = end
        assert c.hexdigest() == want.hexdigest() and c.count == 3
    swapped = EventChecksum()
    swapped.update(ev[np.array([1, 0, 2])])
    assert swapped.hexdigest() != want.hexdigest()
