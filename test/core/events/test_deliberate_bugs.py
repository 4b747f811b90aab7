"""Tests against hand-computed values that catch specific plausible bugs in core/events and the
codecs (each was checked by making the bug in a scratch copy: the test then fails)."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.camera import distort_points, undistort_points
from hrn_vo_ros.core.events.frames import Packetizer
from hrn_vo_ros.core.events.packet_config import paper_framing
from hrn_vo_ros.io import eventpacket

# plumb bob, fx = fy = 100, c = 0, only tangential terms p1 = 0.01, p2 = 0.02; at (0.3, 0.1):
# r2 = 0.1; x_d = 0.3 + 2 p1 x y + p2 (r2 + 2 x^2) = 0.3 + 0.0006 + 0.0056 = 0.3062
#           y_d = 0.1 + p1 (r2 + 2 y^2) + 2 p2 x y = 0.1 + 0.0012 + 0.0012 = 0.1024
DIST = (0.0, 0.0, 0.01, 0.02, 0.0)


def test_plumb_bob_distort_matches_hand_values() -> None:
    u, v = distort_points(100.0, 100.0, 0.0, 0.0, DIST, 0.3, 0.1)
    assert float(u) == pytest.approx(30.62, abs=1e-9)
    assert float(v) == pytest.approx(10.24, abs=1e-9)


def test_plumb_bob_undistort_matches_hand_values() -> None:
    x, y = undistort_points(100.0, 100.0, 0.0, 0.0, DIST, 30.62, 10.24)
    assert float(x) == pytest.approx(0.3, abs=1e-7)
    assert float(y) == pytest.approx(0.1, abs=1e-7)


def test_packetizer_accepts_a_batch_starting_at_the_previous_time() -> None:
    pk = Packetizer(paper_framing(events_per_frame=4))
    a = EventArray.from_arrays(np.array([10, 20, 30]), np.array([1, 2, 3]), np.array([1, 1, 1]),
                               np.array([1, 0, 1]))
    b = EventArray.from_arrays(np.array([30, 40, 50]), np.array([4, 5, 6]), np.array([2, 2, 2]),
                               np.array([0, 1, 0]))
    frames = pk.push(a) + pk.push(b)  # equal times at the boundary are in order
    assert len(frames) == 1
    with pytest.raises(Exception, match='back in time'):
        pk.push(EventArray.from_arrays(np.array([49]), np.array([1]), np.array([1]),
                                       np.array([1])))


def _word(p: int, y: int, x: int, dt: int) -> bytes:
    return (p << 63 | y << 48 | x << 32 | dt).to_bytes(8, 'little')


def test_mono_polarity_against_hand_built_bytes() -> None:
    raw = _word(1, 4, 3, 5) + _word(0, 7, 9, 6)
    ev = eventpacket.decode_mono(raw, time_base=100)
    assert ev.p.tolist() == [1, 0]
    assert ev.x.tolist() == [3, 9] and ev.y.tolist() == [4, 7] and ev.t.tolist() == [105, 106]
    src = EventArray.from_arrays(np.array([105, 106]), np.array([3, 9]), np.array([4, 7]),
                                 np.array([1, 0]))
    time_base, payload = eventpacket.encode_mono(src, time_base=100)
    assert time_base == 100 and payload.tobytes() == raw


def test_evt3_vector_advance_carries_into_the_next_packet() -> None:
    def words(*ws: int) -> bytes:
        return np.array(ws, '<u2').tobytes()

    first = words(8 << 12 | 0, 6 << 12 | 1, 0 << 12 | 5,          # TIME_HIGH, TIME_LOW, ADDR_Y
                  3 << 12 | 1 << 11 | 10, 4 << 12 | 0b1)          # VECT_BASE_X x=10 p=1, VECT_12
    second = words(5 << 12 | 0b1)                                 # VECT_8: base x is 10 + 12
    dec = eventpacket.Evt3Decoder()
    a, b = dec.decode(first), dec.decode(second)
    assert a.x.tolist() == [10]
    assert b.x.tolist() == [22] and b.y.tolist() == [5] and b.p.tolist() == [1]
