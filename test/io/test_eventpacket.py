"""EventPacket codecs: mono round trips, evt3 against hand-made word streams, dvs_msgs layouts."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray, EventChecksum
from hrn_vo_ros.errors import DecodeError
from hrn_vo_ros.io import bags, eventpacket
from hrn_vo_ros.io.ros1bag import encode_dvs_ros1, ros1_typestore


def random_events(rng: np.random.Generator, n: int, *, t0: int = 10**9, span: int = 10**8,
                  width: int = 1280, height: int = 720) -> EventArray:
    return EventArray.from_arrays(np.sort(rng.integers(t0, t0 + span, n)),
                                  rng.integers(0, width, n), rng.integers(0, height, n),
                                  rng.integers(0, 2, n))


def same(a: EventArray, b: EventArray) -> bool:
    ca, cb = EventChecksum(), EventChecksum()
    ca.update(a)
    cb.update(b)
    return (ca.count, ca.hexdigest()) == (cb.count, cb.hexdigest())


def test_mono_round_trip_and_layout(rng: np.random.Generator) -> None:
    ev = random_events(rng, 1000, width=65535, height=32767)
    time_base, payload = eventpacket.encode_mono(ev)
    assert time_base == ev.t[0] and payload.dtype == np.uint8 and payload.size == 8000
    assert same(eventpacket.decode_mono(payload, time_base=time_base), ev)
    word = int(np.frombuffer(payload[8:16].tobytes(), '<u8')[0])
    assert word == (int(ev.p[1]) << 63 | int(ev.y[1]) << 48 | int(ev.x[1]) << 32
                    | int(ev.t[1] - time_base))
    big = payload.view('<u8').astype('>u8').view(np.uint8)
    assert same(eventpacket.decode_mono(big, time_base=time_base, is_bigendian=True), ev)
    assert same(eventpacket.decode('mono', payload.tobytes(), time_base=time_base), ev)


def test_mono_packets_at_once_equal_one_by_one(rng: np.random.Generator) -> None:
    ev = random_events(rng, 1000, width=65535, height=32767)
    bounds = np.array([0, 1, 400, 401, 999, 1000])
    time_bases, payload = eventpacket.encode_mono_packets(ev, bounds)
    for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        time_base, one = eventpacket.encode_mono(ev[a:b])
        assert time_bases[i] == time_base
        assert payload[8 * a:8 * b].tobytes() == one.tobytes()
    with pytest.raises(DecodeError, match='at least one event'):
        eventpacket.encode_mono_packets(ev, np.array([0, 5, 5, 1000]))


def test_mono_rejects_long_packets_and_bad_payloads(rng: np.random.Generator) -> None:
    ev = EventArray.from_arrays(np.array([0, 2**32]), np.zeros(2), np.zeros(2), np.zeros(2))
    with pytest.raises(DecodeError, match='4.29 s'):
        eventpacket.encode_mono(ev)
    with pytest.raises(DecodeError, match='multiple of 8'):
        eventpacket.decode_mono(b'\x00' * 12, time_base=0)
    with pytest.raises(DecodeError, match="unknown EventPacket encoding 'libcaer_cmp'"):
        eventpacket.decode('libcaer_cmp', b'', time_base=0)


def words(*w: int) -> bytes:
    return np.array(w, '<u2').tobytes()


def test_evt3_hand_made_stream() -> None:
    # TIME_HIGH 1, TIME_LOW 2 -> t = (1 << 12 | 2) us; ADDR_Y 5; ADDR_X x=7 ON;
    # VECT_BASE_X x=10 OFF; VECT_12 bits 0 and 2; VECT_8 bit 0 (x = 10 + 12); TIME_LOW 3;
    # EXT_TRIGGER and OTHERS ignored; ADDR_X x=1 OFF at the new time.
    stream = words(0x8001, 0x6002, 0x0005, 0x2000 | 1 << 11 | 7, 0x300A, 0x4005, 0x5001,
                   0x6003, 0xA001, 0xE019, 0x2001)
    ev = eventpacket.Evt3Decoder().decode(stream)
    t1, t2 = (1 << 12 | 2) * 1000, (1 << 12 | 3) * 1000
    assert ev.t.tolist() == [t1, t1, t1, t1, t2]
    assert ev.x.tolist() == [7, 10, 12, 22, 1]
    assert ev.y.tolist() == [5] * 5
    assert ev.p.tolist() == [1, 0, 0, 0, 0]


def test_evt3_skips_until_valid_time_and_tracks_rollover() -> None:
    dec = eventpacket.Evt3Decoder()
    # events before the first TIME_HIGH + TIME_LOW pair are dropped (as the C++ decoder does)
    assert len(dec.decode(words(0x0003, 0x2004, 0x8FFF))) == 0
    ev = dec.decode(words(0x6001, 0x0003, 0x2004))
    assert ev.t.tolist() == [(0xFFF << 12 | 1) * 1000]
    ev = dec.decode(words(0x8000, 0x6002, 0x2005))  # high goes 0xFFF -> 0: a rollover
    assert ev.t.tolist() == [((1 << 24) + 2) * 1000] and ev.y.tolist() == [3]
    ev = dec.decode(words(0x8005, 0x8002, 0x6000, 0x2006))  # small back-step: jitter, no roll
    assert ev.t.tolist() == [((1 << 24) + (2 << 12)) * 1000]


def test_evt3_round_trip_across_arbitrary_packet_splits(rng: np.random.Generator) -> None:
    n = 3000
    t = np.sort(rng.integers(0, 40_000_000, n)) * 1000  # 40 s of us stamps: two rollovers
    t[100:130] = t[100]  # a burst at one time and row: vector words
    y = rng.integers(0, 720, n)
    y[100:130] = 9
    x = rng.integers(0, 1280, n)
    x[100:130] = np.arange(100, 160, 2)
    p = rng.integers(0, 2, n)
    p[100:130] = 1
    ev = EventArray.from_arrays(t, x, y, p)
    for vectors in (False, True):
        stream = eventpacket.encode_evt3(ev, vectors=vectors)
        codes = set((stream.view('<u2') >> 12).tolist())
        assert ({3, 4, 5} <= codes) == vectors
        dec = eventpacket.PacketDecoder()
        cuts = np.sort(rng.choice(np.arange(1, stream.size // 2), 20, replace=False)) * 2
        parts = [dec.decode('evt3', chunk, time_base=0)
                 for chunk in np.split(stream, cuts)]
        assert same(EventArray.concatenate(parts), ev)


def test_evt3_drops_out_of_sensor_and_rejects_unknown_words() -> None:
    dec = eventpacket.Evt3Decoder(width=10, height=10)
    ev = dec.decode(words(0x8000, 0x6000, 0x0003, 0x2009, 0x200A, 0x0010, 0x2001))
    assert ev.x.tolist() == [9] and dec.dropped == 2
    with pytest.raises(DecodeError, match='unknown type 12'):
        eventpacket.Evt3Decoder().decode(words(0x8000, 0xC000))
    with pytest.raises(DecodeError, match='16-bit'):
        eventpacket.Evt3Decoder().decode(b'\x00\x80\x00')


def test_dvs_ros1_matches_rosbags(rng: np.random.Generator) -> None:
    ev = random_events(rng, 50, width=240, height=180)
    raw = encode_dvs_ros1(ev, stamp_ns=5_000_000_007, seq=3, frame_id='dvs', width=240,
                          height=180)
    msg = ros1_typestore().deserialize_ros1(raw, 'dvs_msgs/msg/EventArray')
    assert [(e.x, e.y, e.ts.sec * 10**9 + e.ts.nanosec, int(e.polarity)) for e in msg.events] \
        == list(zip(ev.x.tolist(), ev.y.tolist(), ev.t.tolist(), ev.p.tolist(), strict=True))
    back = eventpacket.decode_dvs_ros1(raw)
    assert same(back.events, ev) and back.stamp_ns == 5_000_000_007 and back.frame_id == 'dvs'
    with pytest.raises(DecodeError, match='truncated'):
        eventpacket.decode_dvs_ros1(raw[:-5])


@pytest.mark.parametrize('frame_id', ['', 'a', 'dvs', 'davis'])
def test_dvs_cdr_matches_rosbags(frame_id: str) -> None:
    ts = bags.typestore()
    T = ts.types
    events = [T['dvs_msgs/msg/Event'](x=i, y=2 * i + 1, ts=T['builtin_interfaces/msg/Time'](
        sec=i, nanosec=7 * i), polarity=bool(i % 2)) for i in range(5)]
    msg = T['dvs_msgs/msg/EventArray'](
        header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=3, nanosec=4),
                                        frame_id=frame_id), height=180, width=240, events=events)
    arr = eventpacket.decode_dvs_cdr(ts.serialize_cdr(msg, 'dvs_msgs/msg/EventArray'))
    assert (arr.frame_id, arr.width, arr.height, arr.stamp_ns) == (frame_id, 240, 180,
                                                                    3_000_000_004)
    assert arr.events.x.tolist() == [0, 1, 2, 3, 4] and arr.events.y.tolist() == [1, 3, 5, 7, 9]
    assert arr.events.t.tolist() == [i * 1_000_000_007 for i in range(5)]
    assert arr.events.p.tolist() == [0, 1, 0, 1, 0]
