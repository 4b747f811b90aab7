"""Codecs of ``event_camera_msgs/msg/EventPacket`` payloads, vectorised numpy on bytes (no rclpy).

The encodings follow the formats of ros-event-camera/event_camera_codecs; each has its module
in :mod:`hrn_vo_ros.io.codecs`, where its word layout is documented:

* ``mono`` (:mod:`~hrn_vo_ros.io.codecs.mono`): one 64-bit word per event, stateless.
* ``evt3`` (:mod:`~hrn_vo_ros.io.codecs.evt3`, Prophesee): 16-bit words, change events and
  external-trigger events, stateful across packets.
* ``libcaer_cmp`` (:mod:`~hrn_vo_ros.io.codecs.libcaer`, iniVation DAVIS/DVXplorer through
  libcaer_driver): 16-bit words, stateful across packets.
* ``libcaer`` (same module): uncompressed 8-byte libcaer polarity records, stateless.
* legacy ``dvs_msgs/EventArray`` (:mod:`~hrn_vo_ros.io.codecs.dvs`): :func:`decode_dvs_ros1`,
  :func:`decode_dvs_cdr`.

Public API: :func:`decode` (stateless dispatch on the encoding name), :class:`PacketDecoder`
(stateful dispatch, one per subscribed topic; :meth:`PacketDecoder.decode_all` also returns
the trigger events), the per-encoding decoders and the test encoders :func:`encode_mono`,
:func:`encode_mono_packets`, :func:`encode_evt3`. An unknown encoding or a corrupt payload
raises :class:`~hrn_vo_ros.errors.DecodeError`.
"""

from __future__ import annotations

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import DecodeError
from hrn_vo_ros.io.codecs.common import TriggerArray, U8
from hrn_vo_ros.io.codecs.dvs import decode_dvs_cdr, decode_dvs_ros1, DvsArray
from hrn_vo_ros.io.codecs.evt3 import encode_evt3, Evt3Decoder
from hrn_vo_ros.io.codecs.libcaer import decode_libcaer, LibcaerCmpDecoder
from hrn_vo_ros.io.codecs.mono import decode_mono, encode_mono, encode_mono_packets, MONO_MAX_DT

__all__ = ['ENCODINGS', 'MONO_MAX_DT', 'DvsArray', 'Evt3Decoder', 'LibcaerCmpDecoder',
           'PacketDecoder', 'TriggerArray', 'decode', 'decode_dvs_cdr', 'decode_dvs_ros1',
           'decode_libcaer', 'decode_mono', 'encode_evt3', 'encode_mono', 'encode_mono_packets']

ENCODINGS = ('mono', 'evt3', 'libcaer_cmp', 'libcaer')
"""Encodings :func:`decode` and :class:`PacketDecoder` understand."""


def decode(encoding: str, payload: bytes | U8, *, time_base: int, is_bigendian: bool = False,
           width: int | None = None, height: int | None = None) -> EventArray:
    """Decode one packet without state from earlier packets.

    For ``evt3`` and ``libcaer_cmp`` this only works on packets that carry all the state they
    need (evt3: their own time words); streams should use :class:`PacketDecoder` instead.

    Raises:
        DecodeError: on an unknown encoding (naming the supported ones) or a corrupt payload.
    """
    return PacketDecoder(width=width, height=height).decode(
        encoding, payload, time_base=time_base, is_bigendian=is_bigendian)


class PacketDecoder:
    """Decodes the EventPacket payloads of one topic in order (keeps evt3 / libcaer_cmp state).

    Args:
        width: Sensor width for dropping out-of-sensor evt3 / libcaer_cmp events (optional).
        height: Sensor height, likewise.
    """

    def __init__(self, *, width: int | None = None, height: int | None = None) -> None:
        self._evt3 = Evt3Decoder(width=width, height=height)
        self._cmp = LibcaerCmpDecoder(width=width, height=height)

    def reset(self) -> None:
        """Forget the stream state (evt3 time and addresses, libcaer_cmp addresses): the next
        packet starts a new stream, as after a camera restart or a looped bag."""
        self._evt3.reset()
        self._cmp.x = self._cmp.base_y = self._cmp.polarity = 0

    @property
    def dropped(self) -> int:
        """Events dropped so far for lying outside the sensor."""
        return self._evt3.dropped + self._cmp.dropped

    def decode(self, encoding: str, payload: bytes | U8, *, time_base: int,
               is_bigendian: bool = False) -> EventArray:
        """Change events of one packet at sensor time (int64 ns).

        Raises:
            DecodeError: on an unknown encoding or a corrupt payload.
        """
        return self.decode_all(encoding, payload, time_base=time_base,
                               is_bigendian=is_bigendian)[0]

    def decode_all(self, encoding: str, payload: bytes | U8, *, time_base: int,
                   is_bigendian: bool = False) -> tuple[EventArray, TriggerArray]:
        """Change events and external-trigger events (evt3 only) of one packet.

        Raises:
            DecodeError: on an unknown encoding or a corrupt payload.
        """
        if encoding == 'evt3':
            return self._evt3.decode_all(payload, is_bigendian=is_bigendian)
        if encoding == 'mono':
            ev = decode_mono(payload, time_base=time_base, is_bigendian=is_bigendian)
        elif encoding == 'libcaer_cmp':
            ev = self._cmp.decode(payload, time_base=time_base, is_bigendian=is_bigendian)
        elif encoding == 'libcaer':
            ev = decode_libcaer(payload, time_base=time_base, is_bigendian=is_bigendian)
        else:
            raise DecodeError(f'unknown EventPacket encoding {encoding!r}; supported: '
                              f'{", ".join(ENCODINGS)} (convert other streams with '
                              'event_camera_tools first)')
        return ev, TriggerArray.empty()
