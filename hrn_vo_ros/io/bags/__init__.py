"""ROS 2 bags through rosbags: our typestore, a crash-safe writer, a reader that refuses half bags.

* :func:`typestore` is ``Stores.ROS2_JAZZY`` plus the interface definitions shipped in
  ``hrn_vo_ros/io/msg/`` (``event_camera_msgs``, ``dvs_msgs``, ``tf2_msgs``), registered with
  ``get_types_from_msg``. Bags written with it carry every message definition and RIHS01 hash.
* :class:`BagWriter` writes ``DST`` as ``DST.partial/<name>`` and renames it to ``DST`` only when
  closed without error, so an interrupted write never leaves something that looks like a bag at
  ``DST``; it refuses to overwrite. MCAP files get their chunk, data-section and summary CRCs
  (rosbags writes zeros) before the rename. Each topic records its offered QoS profile
  (:data:`EVENTS_QOS` best-effort like the camera drivers, :data:`SENSOR_QOS`,
  :data:`RELIABLE_QOS`).
* :meth:`BagWriter.flush` closes the open MCAP chunk and hands the bytes to the operating
  system; :func:`recover_bag` (``hrn-vo recover``) rewrites the complete chunks of a ``.partial``
  bag that a killed recorder left as a finished bag.
* :func:`open_bag` opens a ROS 2 bag (sqlite3 or MCAP) for reading: metadata versions 5 to 9
  (rosbag2 of Foxy to Jazzy), with an empty ``storage_identifier`` (older rosbag2 writes one)
  inferred from the storage files' suffixes (``.mcap``, ``.db3``); ``.partial`` paths, missing
  or corrupt bags raise :class:`~hrn_vo_ros.errors.BagError`, and so do metadata message
  counts that differ from the storage's, failed MCAP summary CRCs or sqlite checks, and bag-time
  spans over :data:`MAX_BAG_SPAN_NS`.
* :func:`verify_bag` checks a whole bag: every CRC, every count, every event message decoded
  and sane, and the event checksum ``hrn-vo convert`` stores in ``custom_data``.
* :func:`iter_bag_events` streams the decoded events of an EventPacket topic (any encoding
  :mod:`hrn_vo_ros.io.eventpacket` knows) or a legacy ``dvs_msgs/msg/EventArray`` topic.
* :func:`event_packet_cdr` serialises an EventPacket straight to CDR bytes (byte-identical to
  rosbags' serialiser, about 10x faster for small packets).

Modules (import from this package; the split is by concern):

* :mod:`~hrn_vo_ros.io.bags.types`: typestore, message type names, storages, QoS profiles.
* :mod:`~hrn_vo_ros.io.bags.cdr`: the fast CDR serialisers.
* :mod:`~hrn_vo_ros.io.bags.writing`: :class:`BagWriter`.
* :mod:`~hrn_vo_ros.io.bags.reading`: :func:`open_bag`, metadata, message and event iteration.
* :mod:`~hrn_vo_ros.io.bags.mcap`: the MCAP record walk and its CRCs.
* :mod:`~hrn_vo_ros.io.bags.storage`: storage counts and spans against ``metadata.yaml``.
* :mod:`~hrn_vo_ros.io.bags.verify`: :func:`verify_bag` and the ``custom_data`` keys.
* :mod:`~hrn_vo_ros.io.bags.recovery`: :func:`recover_bag`.
"""

from __future__ import annotations

from hrn_vo_ros.io.bags.cdr import event_packet_cdr, imu_cdr_batch, pose_cdr_batch
from hrn_vo_ros.io.bags.mcap import (
    check_mcap_crcs,
    MCAP_MAGIC,
    McapChunk,
    McapScan,
    scan_mcap,
)
from hrn_vo_ros.io.bags.reading import (
    bag_storage,
    BagMessage,
    BagReader,
    check_packet_events,
    iter_bag_events,
    iter_messages,
    METADATA_VERSIONS,
    open_bag,
    STORAGE_SUFFIXES,
)
from hrn_vo_ros.io.bags.recovery import recover_bag, RECOVERED_KEY, Recovery
from hrn_vo_ros.io.bags.storage import (
    check_storage,
    MAX_BAG_SPAN_NS,
    storage_facts,
    StorageFacts,
)
from hrn_vo_ros.io.bags.types import (
    DVS_EVENT_ARRAY,
    EVENT_PACKET,
    EVENTS_QOS,
    make_qos,
    MSG_DIR,
    qos_profiles,
    RELIABLE_QOS,
    SENSOR_QOS,
    Storage,
    STORAGES,
    typestore,
)
from hrn_vo_ros.io.bags.verify import (
    BagVerification,
    CHECKSUM_KEY,
    COUNT_KEY,
    custom_data,
    TOPIC_KEY,
    verify_bag,
)
from hrn_vo_ros.io.bags.writing import _check_target as _check_target  # used by io/convert.py
from hrn_vo_ros.io.bags.writing import BagWriter

__all__ = [
    'BagMessage',
    'BagReader',
    'BagVerification',
    'BagWriter',
    'CHECKSUM_KEY',
    'COUNT_KEY',
    'DVS_EVENT_ARRAY',
    'EVENT_PACKET',
    'EVENTS_QOS',
    'MAX_BAG_SPAN_NS',
    'MCAP_MAGIC',
    'METADATA_VERSIONS',
    'MSG_DIR',
    'McapChunk',
    'McapScan',
    'RECOVERED_KEY',
    'RELIABLE_QOS',
    'Recovery',
    'SENSOR_QOS',
    'STORAGES',
    'STORAGE_SUFFIXES',
    'Storage',
    'StorageFacts',
    'TOPIC_KEY',
    'bag_storage',
    'check_mcap_crcs',
    'check_packet_events',
    'check_storage',
    'custom_data',
    'event_packet_cdr',
    'imu_cdr_batch',
    'iter_bag_events',
    'iter_messages',
    'make_qos',
    'open_bag',
    'pose_cdr_batch',
    'qos_profiles',
    'recover_bag',
    'scan_mcap',
    'storage_facts',
    'typestore',
    'verify_bag',
]
