"""Codecs of ``event_camera_msgs/msg/EventPacket`` payloads, vectorised numpy on bytes (no rclpy).

Layouts (``docs/ros_notes.md`` §1, following ros-event-camera/event_camera_codecs):

* ``mono``: one 64-bit word per event in the byte order given by ``is_bigendian``:
  ``p << 63 | y << 48 | x << 32 | dt`` with ``p`` 1 bit, ``y`` 15 bits, ``x`` 16 bits and ``dt`` a
  uint32 of nanoseconds; the event's sensor time is ``time_base + dt``, so a packet spans at most
  2^32 - 1 ns (4.29 s).
* ``evt3`` (Prophesee, what ``metavision_driver`` publishes): 16-bit words, type in the top 4 bits.
  ``ADDR_Y`` (0) sets y; ``ADDR_X`` (2) emits one event at (x, y) with its polarity;
  ``VECT_BASE_X`` (3) sets base x and polarity; ``VECT_12`` (4) / ``VECT_8`` (5) emit events at
  ``base_x + i`` for every set bit i of their mask and advance base x by 12 / 8; ``TIME_LOW`` (6)
  and ``TIME_HIGH`` (8) set the low and high 12 bits of the microsecond time; a TIME_HIGH that goes
  back by more than 10 counts is a rollover of the 24-bit time (+2^24 us). ``time_base`` is unused;
  the time is ``(high | low) * 1000`` ns. Codes 7, 9, 10, 14, 15 (continued, padding, trigger,
  others) carry no CD event. Decoding is stateful across packets (:class:`Evt3Decoder`); like the
  C++ decoder, words before the first TIME_HIGH + TIME_LOW pair are skipped.
* legacy ``dvs_msgs/EventArray``: :func:`decode_dvs_ros1` reads ROS 1 serialised messages (events
  are packed 13-byte records ``x u2, y u2, sec u4, nsec u4, polarity u1``), :func:`decode_dvs_cdr`
  ROS 2 CDR ones (16-byte aligned records after the first 14-byte one).

Public API: :func:`encode_mono`, :func:`encode_mono_packets`, :func:`decode_mono`,
:class:`Evt3Decoder`, :func:`encode_evt3` (for tests and benchmarks), :func:`decode`
(stateless dispatch on the encoding name), :class:`PacketDecoder` (stateful dispatch, one per
subscribed topic), :func:`decode_dvs_ros1`, :func:`decode_dvs_cdr`. An unknown encoding or a
corrupt payload raises :class:`~hrn_vo_ros.errors.DecodeError`.
"""

from __future__ import annotations

from dataclasses import dataclass
import struct

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import DecodeError

ENCODINGS = ('mono', 'evt3')
"""Encodings :func:`decode` understands."""

MONO_MAX_DT = (1 << 32) - 1
"""Largest ``dt`` of a mono word (ns): a mono packet spans at most this."""

_U8 = NDArray[np.uint8]


# ------------------------------------------------------------------------------------ mono

def encode_mono(ev: EventArray, *, time_base: int | None = None) -> tuple[int, _U8]:
    """Encode events as a ``mono`` payload (little-endian words).

    Args:
        ev: The packet's events, sorted by time.
        time_base: Packet time base in ns; default the first event's time.

    Returns:
        ``(time_base, payload)`` with ``payload`` a uint8 array of ``8 * len(ev)`` bytes.

    Raises:
        DecodeError: if an event lies before ``time_base`` or more than 2^32 - 1 ns after it,
            or x >= 65536, y >= 32768, p not 0/1.

    Shapes:
        payload: (8 n,) uint8.
    """
    n = len(ev)
    if time_base is None:
        time_base = int(ev.t[0]) if n else 0
    if n == 0:
        return time_base, np.empty(0, np.uint8)
    dt = ev.t - np.int64(time_base)
    if int(dt.min()) < 0 or int(dt.max()) > MONO_MAX_DT:
        msg = (f'mono packet spans {int(dt.min())}..{int(dt.max())} ns from time_base; it must '
               f'lie within 0..{MONO_MAX_DT} ns (4.29 s): use shorter packets')
        raise DecodeError(msg)
    if int(ev.y.max()) >= 1 << 15 or int(ev.p.max()) > 1:
        raise DecodeError('mono words hold y < 32768 and polarity 0/1')
    words = (dt.astype(np.uint64) | (ev.x.astype(np.uint64) << np.uint64(32))
             | (ev.y.astype(np.uint64) << np.uint64(48))
             | (ev.p.astype(np.uint64) << np.uint64(63)))
    return time_base, words.astype('<u8', copy=False).view(np.uint8)


def encode_mono_packets(ev: EventArray, bounds: NDArray[np.int64],
                        ) -> tuple[NDArray[np.int64], _U8]:
    """Encode many ``mono`` packets at once: packet i holds ``ev[bounds[i]:bounds[i + 1]]``.

    Each packet's ``time_base`` is its first event's time; its payload is
    ``payload[8 * bounds[i]:8 * bounds[i + 1]]``. Same words as :func:`encode_mono`.

    Raises:
        DecodeError: as :func:`encode_mono` (a packet spanning more than 2^32 - 1 ns, ...).

    Shapes:
        bounds: (k + 1,) increasing, from 0 to len(ev); returns time_bases (k,) and
        payload (8 len(ev),) uint8.
    """
    sizes = np.diff(bounds)
    if np.any(sizes <= 0):
        raise DecodeError('mono packets must hold at least one event each')
    time_bases = ev.t[bounds[:-1]]
    dt = ev.t - np.repeat(time_bases, sizes)
    if len(ev) and (int(dt.min()) < 0 or int(dt.max()) > MONO_MAX_DT):
        raise DecodeError(f'a mono packet spans more than {MONO_MAX_DT} ns (4.29 s) or is not '
                          'sorted by time: use shorter packets')
    if len(ev) and (int(ev.y.max()) >= 1 << 15 or int(ev.p.max()) > 1):
        raise DecodeError('mono words hold y < 32768 and polarity 0/1')
    words = (dt.astype(np.uint64) | (ev.x.astype(np.uint64) << np.uint64(32))
             | (ev.y.astype(np.uint64) << np.uint64(48))
             | (ev.p.astype(np.uint64) << np.uint64(63)))
    return time_bases, words.astype('<u8', copy=False).view(np.uint8)


def decode_mono(payload: bytes | _U8, *, time_base: int, is_bigendian: bool = False,
                ) -> EventArray:
    """Decode a ``mono`` payload into events at sensor time ``time_base + dt``.

    Raises:
        DecodeError: if the payload is not a whole number of 8-byte words.
    """
    buf = np.frombuffer(payload, np.uint8) if not isinstance(payload, np.ndarray) else payload
    if buf.size % 8:
        raise DecodeError(f'mono payload of {buf.size} bytes is not a multiple of 8 '
                          '(truncated or not mono)')
    w = buf.view('>u8' if is_bigendian else '<u8')
    t = (w & np.uint64(0xFFFFFFFF)).astype(np.int64)
    t += np.int64(time_base)
    x = ((w >> np.uint64(32)) & np.uint64(0xFFFF)).astype(np.uint16)
    y = ((w >> np.uint64(48)) & np.uint64(0x7FFF)).astype(np.uint16)
    p = (w >> np.uint64(63)).astype(np.uint8)
    return EventArray(t, x, y, p)


# ------------------------------------------------------------------------------------ evt3

_ADDR_Y, _ADDR_X, _VECT_BASE_X, _VECT_12, _VECT_8 = 0, 2, 3, 4, 5
_TIME_LOW, _TIME_HIGH = 6, 8
_IGNORED = frozenset((7, 9, 10, 14, 15))
_KNOWN = frozenset((0, 2, 3, 4, 5, 6, 8)) | _IGNORED
_ROLLOVER_MIN_BACKSTEP = 10  # a TIME_HIGH going back less than this is jitter, not a rollover


_KNOWN_TABLE = np.zeros(16, bool)
_KNOWN_TABLE[list(_KNOWN)] = True


def _ffill_at(mask: NDArray[np.bool_], values: NDArray[np.int64], initial: int,
              pos: NDArray[np.intp]) -> NDArray[np.int64]:
    """At positions ``pos``: the value of the last word at or before it where ``mask`` holds.

    ``values`` holds one value per True of ``mask`` (in order); ``initial`` applies where no
    such word precedes (the state carried from the previous packet).

    Shapes:
        mask: (n,); values: (mask.sum(),); pos: (m,) -> (m,).
    """
    if values.size == 0:
        return np.full(pos.size, initial, np.int64)
    k = np.cumsum(mask)[pos] - 1
    return np.where(k >= 0, values[np.maximum(k, 0)], initial).astype(np.int64, copy=False)


@dataclass(slots=True)
class Evt3Decoder:
    """Stateful EVT3 decoder: feed the packets of one stream in order to :meth:`decode`.

    Args:
        width: Sensor width; events at x >= width are dropped (as the C++ decoder does).
        height: Sensor height; events at y >= height are dropped.
    """

    width: int | None = None
    height: int | None = None
    y: int = 0
    time_low: int = 0
    time_high: int = 0  # (high 12 bits << 12) + rollovers * 2^24, in us
    base_x: int = 0
    polarity: int = 0
    valid_time: bool = False
    seen_high: bool = False
    dropped: int = 0

    def decode(self, payload: bytes | _U8, *, is_bigendian: bool = False) -> EventArray:
        """Decode one packet's payload, continuing from the previous packet's state.

        Raises:
            DecodeError: on an odd byte count or an unknown word type.
        """
        buf = np.frombuffer(payload, np.uint8) if not isinstance(payload, np.ndarray) else payload
        if buf.size % 2:
            raise DecodeError(f'evt3 payload of {buf.size} bytes is not a whole number of '
                              '16-bit words')
        w = buf.view('>u2' if is_bigendian else '<u2').astype(np.int64)
        code = w >> 12
        bad = ~_KNOWN_TABLE[code]
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DecodeError(f'evt3 word {i} has unknown type {int(code[i])} '
                              f'(0x{int(w[i]):04x}): not an evt3 stream, or corrupt')
        n = w.size
        if n == 0:
            return EventArray.empty()
        if not self.valid_time:
            code = code.copy()
            start = self._find_valid_time(w, code)
            code[:start] = np.where(np.isin(code[:start], (_TIME_LOW, _TIME_HIGH)),
                                    code[:start], 7)

        # words that carry events (ADDR_X: one at bit 0; vectors: their masks), plus the last
        # word, at which the state for the next packet is read
        is_x = code == _ADDR_X
        is_v12, is_v8 = code == _VECT_12, code == _VECT_8
        rows = np.flatnonzero(is_x | is_v12 | is_v8)
        pos = np.append(rows, n - 1)

        # time: TIME_HIGH with rollovers and TIME_LOW, each the last one before the word
        is_high = code == _TIME_HIGH
        highs = w[is_high] & 0xFFF
        if highs.size:
            prev = np.concatenate(([(self.time_high >> 12) & 0xFFF], highs[:-1]))
            roll = (highs < prev) & (prev - highs > _ROLLOVER_MIN_BACKSTEP)
            base = (self.time_high >> 24) << 24
            highs = base + (np.cumsum(roll) << 24) + (highs << 12)
        high_t = _ffill_at(is_high, highs, self.time_high, pos)
        is_low = code == _TIME_LOW
        low_t = _ffill_at(is_low, w[is_low] & 0xFFF, self.time_low, pos)
        is_y = code == _ADDR_Y
        y_at = _ffill_at(is_y, w[is_y] & 0x7FF, self.y, pos)

        # vectors: base x and polarity from VECT_BASE_X, advanced by each VECT_12 / VECT_8
        is_base = code == _VECT_BASE_X
        step = np.where(is_v12, 12, 0) + np.where(is_v8, 8, 0)
        before = np.cumsum(step) - step  # advance of base x since the packet start
        base_x = _ffill_at(is_base, (w[is_base] & 0x7FF) - before[is_base], self.base_x,
                           pos) + before[pos]
        pol_v = _ffill_at(is_base, (w[is_base] >> 11) & 1, self.polarity, pos)

        # expand: one event per set mask bit, in stream order (word, then bit)
        wr = w[rows]
        xr = is_x[rows]
        masks = np.where(xr, 1, np.where(is_v12[rows], wr & 0xFFF, wr & 0xFF))
        r, col = np.nonzero((masks[:, None] >> np.arange(12)) & 1)
        xr_r = xr[r]
        x = np.where(xr_r, wr[r] & 0x7FF, base_x[r] + col)
        p = np.where(xr_r, (wr[r] >> 11) & 1, pol_v[r])
        y = y_at[r]
        t = (high_t[r] | low_t[r]) * 1000

        # state for the next packet (the last entry of pos is the last word)
        self.time_high = int(high_t[-1])
        self.time_low = int(low_t[-1])
        self.y = int(y_at[-1])
        self.base_x = int(base_x[-1] + step[-1])
        self.polarity = int(pol_v[-1])
        if self.width is not None or self.height is not None:
            keep = np.ones(x.size, bool)
            if self.width is not None:
                keep &= x < self.width
            if self.height is not None:
                keep &= y < self.height
            self.dropped += int(x.size - np.count_nonzero(keep))
            t, x, y, p = t[keep], x[keep], y[keep], p[keep]
        return EventArray.from_arrays(t, x, y, p)

    def _find_valid_time(self, w: NDArray[np.int64], code: NDArray[np.int64]) -> int:
        """Index after the first TIME_LOW that follows a TIME_HIGH (n if none)."""
        highs = np.flatnonzero(code == _TIME_HIGH)
        if self.seen_high:
            first_high = -1
        elif highs.size:
            first_high = int(highs[0])
        else:
            return w.size
        lows = np.flatnonzero((code == _TIME_LOW) & (np.arange(w.size) > first_high))
        self.seen_high = True
        if lows.size == 0:
            return w.size
        self.valid_time = True
        return int(lows[0]) + 1


def encode_evt3(ev: EventArray, *, vectors: bool = False) -> _U8:
    """Encode events as an EVT3 word stream (little-endian), e.g. to test the decoder.

    Times are floored to microseconds. Every word type that carries CD events is produced:
    ``ADDR_X`` singles and, with ``vectors``, ``VECT_BASE_X`` + ``VECT_12``/``VECT_8`` for runs of
    events with the same time, y and polarity at increasing x. The stream opens with TIME_HIGH and
    TIME_LOW so that a fresh decoder accepts it. Written as a plain loop: for tests and
    benchmark inputs, not for speed.

    Shapes:
        return: (2 m,) uint8 for m words.
    """
    out: list[int] = []
    t_us = (ev.t // 1000).tolist()
    xs, ys, ps = ev.x.tolist(), ev.y.tolist(), ev.p.tolist()
    last_high, last_low, last_y = -1, -1, -1
    i, n = 0, len(ev)
    while i < n:
        t = t_us[i]
        high, low = (t >> 12) & 0xFFF, t & 0xFFF
        if (t >> 12) != last_high:
            out.append(_TIME_HIGH << 12 | high)
            last_high, last_low = t >> 12, -1
        if low != last_low:
            out.append(_TIME_LOW << 12 | low)
            last_low = low
        if ys[i] != last_y:
            out.append(_ADDR_Y << 12 | ys[i])
            last_y = ys[i]
        j = i + 1
        if vectors:  # a run: same time, y and polarity, increasing x within 20 pixels
            while (j < n and t_us[j] == t and ys[j] == ys[i] and ps[j] == ps[i]
                   and xs[j] > xs[j - 1] and xs[j] - xs[i] < 20):
                j += 1
        if j - i >= 2:
            out.append(_VECT_BASE_X << 12 | ps[i] << 11 | xs[i])
            mask12 = sum(1 << (xs[k] - xs[i]) for k in range(i, j) if xs[k] - xs[i] < 12)
            out.append(_VECT_12 << 12 | mask12)
            rest = [xs[k] - xs[i] - 12 for k in range(i, j) if xs[k] - xs[i] >= 12]
            if rest:
                out.append(_VECT_8 << 12 | sum(1 << b for b in rest))
            i = j
        else:
            out.append(_ADDR_X << 12 | ps[i] << 11 | xs[i])
            i += 1
    return np.array(out, '<u2').view(np.uint8)


# ------------------------------------------------------------------------------------ dispatch

def decode(encoding: str, payload: bytes | _U8, *, time_base: int, is_bigendian: bool = False,
           width: int | None = None, height: int | None = None) -> EventArray:
    """Decode one packet without state from earlier packets.

    For ``evt3`` this only works on packets that carry their own time words; streams should use
    :class:`PacketDecoder` (or :class:`Evt3Decoder`) instead.

    Raises:
        DecodeError: on an unknown encoding (naming the supported ones) or a corrupt payload.
    """
    return PacketDecoder(width=width, height=height).decode(
        encoding, payload, time_base=time_base, is_bigendian=is_bigendian)


class PacketDecoder:
    """Decodes the EventPacket payloads of one topic in order (keeps evt3 state).

    Args:
        width: Sensor width for dropping out-of-sensor evt3 events (optional).
        height: Sensor height, likewise.
    """

    def __init__(self, *, width: int | None = None, height: int | None = None) -> None:
        self._evt3 = Evt3Decoder(width=width, height=height)

    def decode(self, encoding: str, payload: bytes | _U8, *, time_base: int,
               is_bigendian: bool = False) -> EventArray:
        """Events of one packet at sensor time (int64 ns).

        Raises:
            DecodeError: on an unknown encoding or a corrupt payload.
        """
        if encoding == 'mono':
            return decode_mono(payload, time_base=time_base, is_bigendian=is_bigendian)
        if encoding == 'evt3':
            return self._evt3.decode(payload, is_bigendian=is_bigendian)
        raise DecodeError(f'unknown EventPacket encoding {encoding!r}; supported: '
                          f'{", ".join(ENCODINGS)} (convert libcaer/trigger streams with '
                          'event_camera_tools first)')


# ------------------------------------------------------------------------------------ dvs_msgs

@dataclass(frozen=True, slots=True)
class DvsArray:
    """A decoded legacy ``dvs_msgs/EventArray``: header stamp (ns), frame, size and events."""

    stamp_ns: int
    frame_id: str
    width: int
    height: int
    events: EventArray


_DVS_ROS1 = np.dtype([('x', '<u2'), ('y', '<u2'), ('sec', '<u4'), ('nsec', '<u4'), ('p', 'u1')])
_DVS_CDR = np.dtype({'names': ['x', 'y', 'sec', 'nsec', 'p'],
                     'formats': ['<u2', '<u2', '<i4', '<u4', 'u1'],
                     'offsets': [0, 2, 6, 10, 14], 'itemsize': 16})


def _events_from_records(rec: NDArray[np.void]) -> EventArray:
    t = rec['sec'].astype(np.int64) * 1_000_000_000 + rec['nsec'].astype(np.int64)
    return EventArray.from_arrays(t, rec['x'], rec['y'], rec['p'] != 0)


def decode_dvs_ros1(raw: bytes | memoryview) -> DvsArray:
    """Decode a ROS 1 serialised ``dvs_msgs/EventArray`` (as stored in Event Camera Dataset bags).

    Raises:
        DecodeError: if the message is shorter than its header and event count say.
    """
    try:
        _seq, sec, nsec, flen = struct.unpack_from('<IIII', raw, 0)
        off = 16 + flen
        frame_id = bytes(raw[16:off]).decode('utf-8', 'replace')
        height, width, n = struct.unpack_from('<III', raw, off)
    except struct.error as err:
        raise DecodeError(f'dvs_msgs/EventArray too short for its header: {err}') from err
    off += 12
    if len(raw) < off + 13 * n:
        raise DecodeError(f'dvs_msgs/EventArray says {n} events but holds '
                          f'{(len(raw) - off) // 13}: truncated message')
    rec = np.frombuffer(raw, _DVS_ROS1, count=n, offset=off)
    return DvsArray(sec * 1_000_000_000 + nsec, frame_id, width, height,
                    _events_from_records(rec))


def decode_dvs_cdr(raw: bytes | memoryview) -> DvsArray:
    """Decode a ROS 2 CDR (little-endian) ``dvs_msgs/msg/EventArray`` without per-event objects.

    Raises:
        DecodeError: on big-endian CDR or a message shorter than its event count says.
    """
    if len(raw) < 4 or bytes(raw[:2]) not in (b'\x00\x01', b'\x00\x03'):
        raise DecodeError('not little-endian CDR (encapsulation header 00 01)')
    body = memoryview(raw)[4:]
    try:
        sec, nsec, flen = struct.unpack_from('<iII', body, 0)
        frame_id = bytes(body[12:12 + flen]).rstrip(b'\x00').decode('utf-8', 'replace')
        off = (12 + flen + 3) & ~3
        height, width, n = struct.unpack_from('<III', body, off)
    except struct.error as err:
        raise DecodeError(f'dvs_msgs/EventArray too short for its header: {err}') from err
    off += 12  # 4-aligned: the first record is packed (14 bytes), the others 16-byte aligned
    if n == 0:
        events = EventArray.empty()
    else:
        need = off + 14 + 16 * (n - 1) - 1
        if len(body) < need:
            raise DecodeError(f'dvs_msgs/EventArray says {n} events but is only '
                              f'{len(body)} bytes: truncated message')
        first = np.frombuffer(body, _DVS_ROS1, count=1, offset=off)
        tail = bytes(body[off + 14:]) + b'\x00'  # the last record has no trailing pad
        rest = np.frombuffer(tail, _DVS_CDR, count=n - 1)
        events = EventArray.concatenate([_events_from_records(first),
                                         _events_from_records(rest)])
    return DvsArray(sec * 1_000_000_000 + nsec, frame_id, width, height, events)
