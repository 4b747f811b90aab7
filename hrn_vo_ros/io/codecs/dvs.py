"""Legacy ``dvs_msgs/EventArray`` messages (ROS 1 serialised and ROS 2 CDR), no rclpy.

:func:`decode_dvs_ros1` reads ROS 1 serialised messages (events are packed 13-byte records
``x u2, y u2, sec u4, nsec u4, polarity u1``), :func:`decode_dvs_cdr` ROS 2 CDR ones (16-byte
aligned records after the first 14-byte one).
"""

from __future__ import annotations

from dataclasses import dataclass
import struct

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import DecodeError


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
