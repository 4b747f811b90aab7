"""The bag typestore (ROS 2 Jazzy plus the package's messages), message type names and QoS."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, Literal

from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin
from rosbags.typesys import get_types_from_msg, Stores
from rosbags.typesys import get_typestore as _get_typestore
from rosbags.typesys.store import Typestore

MSG_DIR = Path(__file__).resolve().parent.parent / 'msg'
EVENT_PACKET = 'event_camera_msgs/msg/EventPacket'
DVS_EVENT_ARRAY = 'dvs_msgs/msg/EventArray'

Storage = Literal['mcap', 'sqlite3']
STORAGES: dict[str, StoragePlugin] = {'mcap': StoragePlugin.MCAP,
                                      'sqlite3': StoragePlugin.SQLITE3}

_ZERO = QosTime(0, 0)


def make_qos(*, reliable: bool, depth: int, transient_local: bool = False) -> Qos:
    """A rosbag2 QoS profile record (KEEP_LAST ``depth``; other policies default)."""
    return Qos(history=QosHistory.KEEP_LAST, depth=depth,
               reliability=QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               durability=(QosDurability.TRANSIENT_LOCAL if transient_local
                           else QosDurability.VOLATILE),
               deadline=_ZERO, lifespan=_ZERO, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=_ZERO, avoid_ros_namespace_conventions=False)


EVENTS_QOS = make_qos(reliable=False, depth=1000)
"""Event packets: best effort, volatile, keep last 1000 (metavision/libcaer drivers)."""
SENSOR_QOS = make_qos(reliable=False, depth=10)
"""IMU: best effort, keep last 10 (libcaer driver)."""
RELIABLE_QOS = make_qos(reliable=True, depth=10)
"""Ground truth, camera info: reliable, keep last 10."""


def qos_profiles(conn: Connection) -> list[Qos]:
    """The QoS profiles recorded for a topic (empty when the bag has none)."""
    ext = conn.ext
    return list(getattr(ext, 'offered_qos_profiles', []) or [])


@functools.cache
def typestore() -> Typestore:
    """ROS 2 Jazzy types plus the package's interface definitions (``io/msg/*/*.msg``)."""
    ts = _get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    # Event before EventArray: get_types_from_msg resolves names within one package.
    for path in sorted(MSG_DIR.glob('*/*.msg'), key=lambda p: (p.parent.name, len(p.stem))):
        name = f'{path.parent.name}/msg/{path.stem}'
        if name not in ts.fielddefs:
            types.update(get_types_from_msg(path.read_text(), name))
    ts.register(types)
    return ts
