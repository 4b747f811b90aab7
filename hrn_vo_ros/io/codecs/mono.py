"""The ``mono`` EventPacket encoding: one 64-bit word per event.

Each word, in the byte order the message's ``is_bigendian`` gives, is
``p << 63 | y << 48 | x << 32 | dt`` with ``p`` 1 bit, ``y`` 15 bits, ``x`` 16 bits and ``dt`` a
uint32 of nanoseconds; the event's sensor time is ``time_base + dt``, so a packet spans at most
2^32 - 1 ns (4.29 s). Stateless.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import DecodeError
from hrn_vo_ros.io.codecs.common import as_bytes, check_time_base, U8

MONO_MAX_DT = (1 << 32) - 1
"""Largest ``dt`` of a mono word (ns): a mono packet spans at most this."""


def encode_mono(ev: EventArray, *, time_base: int | None = None) -> tuple[int, U8]:
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
                        ) -> tuple[NDArray[np.int64], U8]:
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


def decode_mono(payload: bytes | U8, *, time_base: int, is_bigendian: bool = False,
                ) -> EventArray:
    """Decode a ``mono`` payload into events at sensor time ``time_base + dt``.

    Raises:
        DecodeError: if the payload is not a whole number of 8-byte words, or ``time_base`` is
            negative or so large that ``time_base + dt`` would overflow int64 ns.
    """
    time_base = check_time_base(time_base, 'mono', MONO_MAX_DT)
    buf = as_bytes(payload)
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
