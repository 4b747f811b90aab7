"""Pieces shared by the payload codecs: byte views, time_base checks, forward fill, triggers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.errors import DecodeError

U8 = NDArray[np.uint8]
"""A payload as a uint8 array."""


def as_bytes(payload: bytes | U8) -> U8:
    """A payload (bytes, bytearray, memoryview or uint8 array) as a uint8 array, no copy."""
    if isinstance(payload, np.ndarray):
        return payload
    return np.frombuffer(payload, np.uint8)


INT64_MAX = (1 << 63) - 1
"""Largest sensor time (int64 ns) an event may have."""


def check_time_base(time_base: int, encoding: str, span_ns: int) -> int:
    """``time_base`` as an int, refused when ``time_base + span_ns`` leaves int64 ns.

    An EventPacket's ``time_base`` is a uint64: values at or above 2^63 (or so close below that
    the packet's own offsets wrap) would turn into negative or overflowing sensor times.

    Args:
        time_base: The packet's ``time_base`` field (ns).
        encoding: The packet encoding, for the message.
        span_ns: The largest offset the encoding can add to ``time_base``.

    Raises:
        DecodeError: for a negative ``time_base`` or one whose events would pass 2^63 - 1 ns.
    """
    tb = int(time_base)
    if tb < 0 or tb > INT64_MAX - span_ns:
        raise DecodeError(f'{encoding} packet time_base {tb} ns is outside 0..'
                          f'{INT64_MAX - span_ns} (its events would overflow int64 ns sensor '
                          'time): a corrupt packet, or a driver writing an invalid time_base')
    return tb


def ffill_at(mask: NDArray[np.bool_], values: NDArray[np.int64], initial: int,
             pos: NDArray[np.intp]) -> NDArray[np.int64]:
    """At positions ``pos``: the value of the last word at or before it where ``mask`` holds.

    Args:
        mask: Which words set the value.
        values: One value per True of ``mask``, in order.
        initial: The value where no such word precedes (the state carried from the
            previous packet).
        pos: Word positions to read the value at.

    Returns:
        The value in force at each position.

    Shapes:
        mask: (n,); values: (mask.sum(),); pos: (m,) -> (m,).
    """
    if values.size == 0:
        return np.full(pos.size, initial, np.int64)
    k = np.cumsum(mask)[pos] - 1
    return np.where(k >= 0, values[np.maximum(k, 0)], initial).astype(np.int64, copy=False)


def expand_masks(masks: NDArray[np.int64], bits: int) -> tuple[NDArray[np.intp],
                                                               NDArray[np.intp]]:
    """Row and bit index of every set bit of ``masks``, in stream order (row, then bit).

    Shapes:
        masks: (m,) -> two (k,) arrays for k set bits.
    """
    r, col = np.nonzero((masks[:, None] >> np.arange(bits)) & 1)
    return r, col


@dataclass(frozen=True, slots=True)
class TriggerArray:
    """External-trigger events: sensor time (int64 ns), trigger channel id and edge.

    ``polarity`` is 1 for a rising edge and 0 for a falling one.
    """

    t: NDArray[np.int64]
    id: NDArray[np.uint8]
    polarity: NDArray[np.uint8]

    @classmethod
    def empty(cls) -> TriggerArray:
        """No trigger events."""
        return cls(np.empty(0, np.int64), np.empty(0, np.uint8), np.empty(0, np.uint8))

    def __len__(self) -> int:
        return int(self.t.size)

    @staticmethod
    def concatenate(parts: list[TriggerArray]) -> TriggerArray:
        """The trigger events of several arrays, in order."""
        if not parts:
            return TriggerArray.empty()
        return TriggerArray(np.concatenate([p.t for p in parts]),
                            np.concatenate([p.id for p in parts]),
                            np.concatenate([p.polarity for p in parts]))


def keep_in_sensor(x: NDArray[np.int64], y: NDArray[np.int64], width: int | None,
                   height: int | None) -> NDArray[np.bool_] | None:
    """Which events lie on the sensor (``x < width``, ``y < height``); None keeps them all.

    Shapes:
        x, y: (n,) -> (n,) or None.
    """
    if not width and not height:
        return None
    keep = np.ones(x.size, bool)
    if width:
        keep &= x < width
    if height:
        keep &= y < height
    return keep
