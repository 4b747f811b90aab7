"""The ``libcaer`` and ``libcaer_cmp`` EventPacket encodings (iniVation cameras, libcaer_driver).

``libcaer`` (uncompressed): 8-byte records of a uint32 ``data`` and an int32 ``timestamp``
(microseconds), as in libcaer's polarity packets: x is ``data >> 17 & 0x7FFF``, y is
``data >> 2 & 0x7FFF`` and the polarity is bit 1. The sensor time is
``time_base + timestamp * 1000`` ns; a timestamp smaller than the previous one in the same
packet is a rollover of the 31-bit counter (+2^31 us from there on). Stateless.

``libcaer_cmp`` (compressed): 16-bit words, the type in the top 4 bits:

* ``TIME_HIGH`` (0) / ``TIME_LOW`` (1): the high and low 12 bits of the microsecond offset from
  the packet's ``time_base``; both start at 0 in every packet, so the sensor time is
  ``time_base + (high << 12 | low) * 1000`` ns.
* ``ADDR_X`` (2): sets x (bits 0-10) for the words after it.
* ``ADDR_Y`` (3): one change event at (x, y = bits 0-10) with polarity bit 11.
* ``VECT_BASE_Y`` (4): base y (bits 0-10) and polarity (bit 11) of the vector words after it.
* ``VECT_8`` (5): one event at (x, base_y + i) for every set bit i of the 8-bit mask, then base
  y advances by 8.

x, base y and the vector polarity carry over from one packet to the next
(:class:`LibcaerCmpDecoder`, one per stream); events outside the sensor are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import DecodeError
from hrn_vo_ros.io.codecs.common import (
    as_bytes,
    check_time_base,
    expand_masks,
    ffill_at,
    INT64_MAX,
    keep_in_sensor,
    U8,
)

CMP_TIME_HIGH, CMP_TIME_LOW, CMP_ADDR_X, CMP_ADDR_Y, CMP_VECT_BASE_Y, CMP_VECT_8 = range(6)
LIBCAER_ROLLOVER_US = 1 << 31
"""The libcaer timestamp counter wraps after this many microseconds."""
CMP_MAX_OFFSET_NS = ((1 << 24) - 1) * 1000
"""Largest offset (ns) a ``libcaer_cmp`` packet adds to its ``time_base``."""


def decode_libcaer(payload: bytes | U8, *, time_base: int, is_bigendian: bool = False,
                   ) -> EventArray:
    """Decode a ``libcaer`` payload into events at sensor time (int64 ns).

    Raises:
        DecodeError: if the payload is not a whole number of 8-byte records, or a sensor time
            would be negative or overflow int64 ns (a corrupt ``time_base`` or timestamp).
    """
    time_base = check_time_base(time_base, 'libcaer', 0)
    buf = as_bytes(payload)
    if buf.size % 8:
        raise DecodeError(f'libcaer payload of {buf.size} bytes is not a multiple of 8 '
                          '(truncated or not libcaer)')
    rec = buf.view(np.dtype([('data', '>u4' if is_bigendian else '<u4'),
                             ('ts', '>i4' if is_bigendian else '<i4')]))
    data = rec['data'].astype(np.int64)
    ts = rec['ts'].astype(np.int64)
    rolls = np.concatenate(([0], np.cumsum(ts[1:] < ts[:-1]))) if ts.size else ts
    off_us = ts + rolls * LIBCAER_ROLLOVER_US
    if off_us.size:
        lo, hi = time_base + int(off_us.min()) * 1000, time_base + int(off_us.max()) * 1000
        if lo < 0 or hi > INT64_MAX:
            raise DecodeError(f'libcaer packet times {lo}..{hi} ns leave 0..{INT64_MAX} ns '
                              f'(time_base {time_base}): a corrupt time_base or timestamp')
    t = np.int64(time_base) + off_us * 1000
    return EventArray.from_arrays(t, (data >> 17) & 0x7FFF, (data >> 2) & 0x7FFF,
                                  (data >> 1) & 1)


@dataclass(slots=True)
class LibcaerCmpDecoder:
    """Stateful ``libcaer_cmp`` decoder: feed the packets of one stream in order.

    Args:
        width: Sensor width; events at x >= width are dropped (as the C++ decoder does).
        height: Sensor height; events at y >= height are dropped.
    """

    width: int | None = None
    height: int | None = None
    x: int = 0
    base_y: int = 0
    polarity: int = 0
    dropped: int = 0

    def decode(self, payload: bytes | U8, *, time_base: int, is_bigendian: bool = False,
               ) -> EventArray:
        """Events of one packet at sensor time (int64 ns), continuing x and the vector state.

        Raises:
            DecodeError: on an odd byte count, an unknown word type, or a ``time_base`` whose
                events would overflow int64 ns.
        """
        time_base = check_time_base(time_base, 'libcaer_cmp', CMP_MAX_OFFSET_NS)
        w, code = _cmp_words(payload, is_bigendian)
        n = w.size
        if n == 0:
            return EventArray.empty()
        is_y, is_v8 = code == CMP_ADDR_Y, code == CMP_VECT_8
        rows = np.flatnonzero(is_y | is_v8)
        pos = np.append(rows, n - 1)
        is_high, is_low, is_x = code == CMP_TIME_HIGH, code == CMP_TIME_LOW, code == CMP_ADDR_X
        offset_us = (ffill_at(is_high, (w[is_high] & 0xFFF) << 12, 0, pos)
                     | ffill_at(is_low, w[is_low] & 0xFFF, 0, pos))
        x_at = ffill_at(is_x, w[is_x] & 0x7FF, self.x, pos)
        base_y, pol = self._vectors(w, code, pos)
        wr, yr = w[rows], is_y[rows]
        r, col = expand_masks(np.where(yr, 1, wr & 0xFF), 8)
        yr_r = yr[r]
        x = x_at[r]
        y = np.where(yr_r, wr[r] & 0x7FF, base_y[r] + col)
        p = np.where(yr_r, (wr[r] >> 11) & 1, pol[r])
        t = np.int64(time_base) + offset_us[r] * 1000
        self.x = int(x_at[-1])
        self.base_y = int(base_y[-1]) + (8 if code[-1] == CMP_VECT_8 else 0)
        self.polarity = int(pol[-1])
        keep = keep_in_sensor(x, y, self.width, self.height)
        if keep is not None:
            self.dropped += int(x.size - np.count_nonzero(keep))
            t, x, y, p = t[keep], x[keep], y[keep], p[keep]
        return EventArray.from_arrays(t, x, y, p)

    def _vectors(self, w: NDArray[np.int64], code: NDArray[np.int64], pos: NDArray[np.intp],
                 ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Base y and polarity in force at the words ``pos`` (before their own advance)."""
        is_base = code == CMP_VECT_BASE_Y
        step = np.where(code == CMP_VECT_8, 8, 0)
        before = np.cumsum(step) - step
        base_y = ffill_at(is_base, (w[is_base] & 0x7FF) - before[is_base], self.base_y,
                          pos) + before[pos]
        pol = ffill_at(is_base, (w[is_base] >> 11) & 1, self.polarity, pos)
        return base_y, pol


def _cmp_words(payload: bytes | U8, is_bigendian: bool) -> tuple[NDArray[np.int64],
                                                                  NDArray[np.int64]]:
    """The payload's 16-bit words and their type codes, checked.

    Raises:
        DecodeError: on an odd byte count or a word type other than 0 to 5.
    """
    buf = as_bytes(payload)
    if buf.size % 2:
        raise DecodeError(f'libcaer_cmp payload of {buf.size} bytes is not a whole number of '
                          '16-bit words')
    w = buf.view('>u2' if is_bigendian else '<u2').astype(np.int64)
    code = w >> 12
    bad = code > CMP_VECT_8
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DecodeError(f'libcaer_cmp word {i} has unsupported type {int(code[i])} '
                          f'(0x{int(w[i]):04x}): not a libcaer_cmp stream, or corrupt')
    return w, code
