"""The ``evt3`` EventPacket encoding (Prophesee EVT 3.0, what ``metavision_driver`` publishes).

16-bit little-endian words, the type in the top 4 bits:

* ``ADDR_Y`` (0): y in bits 0-10 (bit 11 is the system type).
* ``ADDR_X`` (2): one change event at (x = bits 0-10, y) with polarity bit 11.
* ``VECT_BASE_X`` (3): base x (bits 0-10) and polarity (bit 11) of the vector words after it.
* ``VECT_12`` (4) / ``VECT_8`` (5): one event at ``base_x + i`` for every set bit i of the
  12 / 8 bit mask, then base x advances by 12 / 8.
* ``TIME_LOW`` (6) / ``TIME_HIGH`` (8): the low and high 12 bits of the 24-bit microsecond time.
  A TIME_HIGH that goes back by more than 10 counts is a rollover of that time (+2^24 us); a
  smaller back-step is the sensor's bit jitter, not a rollover.
* ``EXT_TRIGGER`` (10): an external-trigger edge, edge (1 rising, 0 falling) in bit 0 and the
  trigger channel id in bits 8-11, at the current time.
* ``CONTINUED_4`` (7), ``CONTINUED_12`` (9), ``OTHERS`` (14), padding (15): no event.

``time_base`` is unused: the sensor time is ``(high | low) * 1000`` ns. Decoding is stateful
across packets (:class:`Evt3Decoder`, one per stream); words before the first TIME_HIGH followed
by a TIME_LOW are skipped, since no time is known for them. :meth:`Evt3Decoder.reset` starts a
new stream (the packetizer node calls it when the event clock resets: without it a restarted
camera's time would continue as one more rollover of the old one).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import DecodeError
from hrn_vo_ros.io.codecs.common import (
    as_bytes,
    expand_masks,
    ffill_at,
    keep_in_sensor,
    TriggerArray,
    U8,
)

ADDR_Y, ADDR_X, VECT_BASE_X, VECT_12, VECT_8 = 0, 2, 3, 4, 5
TIME_LOW, TIME_HIGH, EXT_TRIGGER = 6, 8, 10
_SKIP = 7  # a word type without events, used to blank words before the first valid time
_ROLLOVER_MIN_BACKSTEP = 10  # a TIME_HIGH going back less than this is jitter, not a rollover
_KNOWN_TABLE = np.zeros(16, bool)
_KNOWN_TABLE[[0, 2, 3, 4, 5, 6, 7, 8, 9, 10, 14, 15]] = True


def _words(payload: bytes | U8, is_bigendian: bool) -> tuple[NDArray[np.int64],
                                                              NDArray[np.int64]]:
    """The payload's words and their type codes, checked.

    Raises:
        DecodeError: on an odd byte count or an unknown word type.
    """
    buf = as_bytes(payload)
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
    return w, code


@dataclass(slots=True)
class Evt3Decoder:
    """Stateful EVT3 decoder: feed the packets of one stream in order.

    :meth:`decode` returns the change events, :meth:`decode_all` also the trigger events.

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

    def reset(self) -> None:
        """Start afresh, as for a new stream (a camera restart, a looped bag).

        The time state (the TIME_HIGH / TIME_LOW bits and the rollover count) and the address
        state (y, vector base x and polarity) are dropped; words before the next TIME_HIGH
        followed by a TIME_LOW are skipped again. ``dropped`` keeps counting.
        """
        self.y = self.time_low = self.time_high = self.base_x = self.polarity = 0
        self.valid_time = self.seen_high = False

    def decode(self, payload: bytes | U8, *, is_bigendian: bool = False) -> EventArray:
        """Change events of one packet, continuing from the previous packet's state.

        Raises:
            DecodeError: on an odd byte count or an unknown word type.
        """
        return self.decode_all(payload, is_bigendian=is_bigendian)[0]

    def decode_all(self, payload: bytes | U8, *, is_bigendian: bool = False,
                   ) -> tuple[EventArray, TriggerArray]:
        """Change and external-trigger events of one packet (sensor time, int64 ns).

        Raises:
            DecodeError: on an odd byte count or an unknown word type.
        """
        w, code = _words(payload, is_bigendian)
        n = w.size
        if n == 0:
            return EventArray.empty(), TriggerArray.empty()
        if not self.valid_time:
            start = self._find_valid_time(code)
            code = code.copy()
            head = code[:start]
            code[:start] = np.where((head == TIME_LOW) | (head == TIME_HIGH), head, _SKIP)
        # words that carry events, the trigger words, and the last word (the next state)
        is_x, is_v12, is_v8 = code == ADDR_X, code == VECT_12, code == VECT_8
        rows = np.flatnonzero(is_x | is_v12 | is_v8)
        trig = np.flatnonzero(code == EXT_TRIGGER)
        pos = np.concatenate((rows, trig, [n - 1]))
        t_us = self._times(w, code, pos)
        is_y = code == ADDR_Y
        y_at = ffill_at(is_y, w[is_y] & 0x7FF, self.y, pos)
        base_x, pol, step = self._vectors(w, code, pos)
        m = rows.size
        x, y, p, t = _expand(w[rows], code[rows], base_x[:m], pol[:m], y_at[:m], t_us[:m])
        triggers = TriggerArray(t_us[m:-1] * 1000, ((w[trig] >> 8) & 0xF).astype(np.uint8),
                                (w[trig] & 1).astype(np.uint8))
        self.y = int(y_at[-1])
        self.base_x = int(base_x[-1] + step)
        self.polarity = int(pol[-1])
        keep = keep_in_sensor(x, y, self.width, self.height)
        if keep is not None:
            self.dropped += int(x.size - np.count_nonzero(keep))
            t, x, y, p = t[keep], x[keep], y[keep], p[keep]
        return EventArray.from_arrays(t, x, y, p), triggers

    def _times(self, w: NDArray[np.int64], code: NDArray[np.int64],
               pos: NDArray[np.intp]) -> NDArray[np.int64]:
        """Sensor time (us) at the words ``pos``; keeps the time of the last one as state.

        TIME_HIGH words get their rollovers (+2^24 us) counted; each position reads the last
        TIME_HIGH and TIME_LOW at or before it.
        """
        is_high = code == TIME_HIGH
        highs = w[is_high] & 0xFFF
        if highs.size:
            prev = np.concatenate(([(self.time_high >> 12) & 0xFFF], highs[:-1]))
            roll = (highs < prev) & (prev - highs > _ROLLOVER_MIN_BACKSTEP)
            base = (self.time_high >> 24) << 24
            highs = base + (np.cumsum(roll) << 24) + (highs << 12)
        high_t = ffill_at(is_high, highs, self.time_high, pos)
        is_low = code == TIME_LOW
        low_t = ffill_at(is_low, w[is_low] & 0xFFF, self.time_low, pos)
        self.time_high = int(high_t[-1])
        self.time_low = int(low_t[-1])
        return high_t | low_t

    def _vectors(self, w: NDArray[np.int64], code: NDArray[np.int64], pos: NDArray[np.intp],
                 ) -> tuple[NDArray[np.int64], NDArray[np.int64], int]:
        """Base x and polarity of the vector words at ``pos``, and the last word's x advance.

        VECT_BASE_X sets both; each VECT_12 / VECT_8 advances base x by 12 / 8 after its own
        events.
        """
        is_base = code == VECT_BASE_X
        step = np.where(code == VECT_12, 12, 0) + np.where(code == VECT_8, 8, 0)
        before = np.cumsum(step) - step  # advance of base x since the packet start
        base_x = ffill_at(is_base, (w[is_base] & 0x7FF) - before[is_base], self.base_x,
                          pos) + before[pos]
        pol = ffill_at(is_base, (w[is_base] >> 11) & 1, self.polarity, pos)
        return base_x, pol, int(step[-1])

    def _find_valid_time(self, code: NDArray[np.int64]) -> int:
        """Index after the first TIME_LOW that follows a TIME_HIGH (n if none)."""
        highs = np.flatnonzero(code == TIME_HIGH)
        if self.seen_high:
            first_high = -1
        elif highs.size:
            first_high = int(highs[0])
        else:
            return code.size
        lows = np.flatnonzero((code == TIME_LOW) & (np.arange(code.size) > first_high))
        self.seen_high = True
        if lows.size == 0:
            return code.size
        self.valid_time = True
        return int(lows[0]) + 1


def _expand(wr: NDArray[np.int64], cr: NDArray[np.int64], base_x: NDArray[np.int64],
            pol: NDArray[np.int64], y_at: NDArray[np.int64], t_us: NDArray[np.int64],
            ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64],
                       NDArray[np.int64]]:
    """x, y, p, t (ns) of the events of the event words, in stream order (word, then bit).

    Shapes:
        all inputs: (m,) for m event words -> four (k,) arrays.
    """
    xr = cr == ADDR_X
    masks = np.where(xr, 1, np.where(cr == VECT_12, wr & 0xFFF, wr & 0xFF))
    r, col = expand_masks(masks, 12)
    xr_r = xr[r]
    x = np.where(xr_r, wr[r] & 0x7FF, base_x[r] + col)
    p = np.where(xr_r, (wr[r] >> 11) & 1, pol[r])
    return x, y_at[r], p, t_us[r] * 1000


def encode_evt3(ev: EventArray, *, vectors: bool = False) -> U8:
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
            out.append(TIME_HIGH << 12 | high)
            last_high, last_low = t >> 12, -1
        if low != last_low:
            out.append(TIME_LOW << 12 | low)
            last_low = low
        if ys[i] != last_y:
            out.append(ADDR_Y << 12 | ys[i])
            last_y = ys[i]
        j = i + 1
        if vectors:  # a run: same time, y and polarity, increasing x within 20 pixels
            while (j < n and t_us[j] == t and ys[j] == ys[i] and ps[j] == ps[i]
                   and xs[j] > xs[j - 1] and xs[j] - xs[i] < 20):
                j += 1
        if j - i >= 2:
            out.append(VECT_BASE_X << 12 | ps[i] << 11 | xs[i])
            mask12 = sum(1 << (xs[k] - xs[i]) for k in range(i, j) if xs[k] - xs[i] < 12)
            out.append(VECT_12 << 12 | mask12)
            rest = [xs[k] - xs[i] - 12 for k in range(i, j) if xs[k] - xs[i] >= 12]
            if rest:
                out.append(VECT_8 << 12 | sum(1 << b for b in rest))
            i = j
        else:
            out.append(ADDR_X << 12 | ps[i] << 11 | xs[i])
            i += 1
    return np.array(out, '<u2').view(np.uint8)
