"""End-to-end bag verification: structure, CRCs, message counts and the event checksum."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import yaml

from hrn_vo_ros.errors import IntegrityError
from hrn_vo_ros.io.bags.reading import bag_storage, iter_bag_events, iter_messages, open_bag
from hrn_vo_ros.io.bags.storage import check_storage
from hrn_vo_ros.io.bags.types import DVS_EVENT_ARRAY, EVENT_PACKET

CHECKSUM_KEY = 'hrn_vo_ros.events_sha256'
"""``custom_data`` key of the converted bags' event checksum (:class:`EventChecksum`)."""
COUNT_KEY = 'hrn_vo_ros.events_count'
"""``custom_data`` key of the converted bags' event count."""
TOPIC_KEY = 'hrn_vo_ros.events_topic'
"""``custom_data`` key of the topic the event checksum covers."""


@dataclass(frozen=True, slots=True)
class BagVerification:
    """The outcome of :func:`verify_bag` (every check passed)."""

    path: Path
    storage: str
    counts: dict[str, int]
    event_topic: str | None
    events: int
    checksum: str | None
    stored_checksum: str | None
    chunks_crc_checked: int
    notes: tuple[str, ...]


def custom_data(path: Path | str) -> dict[str, str]:
    """The ``custom_data`` of a bag directory's metadata (empty when absent or a bare file)."""
    path = Path(path)
    if not path.is_dir():
        return {}
    try:
        doc = yaml.safe_load((path / 'metadata.yaml').read_text())
        data = doc['rosbag2_bagfile_information'].get('custom_data') or {}
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return {}
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}


def verify_bag(path: Path | str, *, topic: str | None = None) -> BagVerification:
    """Verify a ROS 2 bag end to end: structure, CRCs, message counts and the event checksum.

    Opens the bag (:func:`open_bag`: metadata against storage counts, MCAP CRCs, sqlite
    ``quick_check``, bag-time span), reads every record (counting them per topic), decodes
    every event message with the sanity checks of :func:`iter_bag_events`, and compares the
    running :class:`~hrn_vo_ros.core.events.arrays.EventChecksum` of the events with the one
    ``hrn-vo convert`` stored in ``custom_data`` (key :data:`CHECKSUM_KEY`).

    Args:
        path: Bag directory (or single storage file).
        topic: Event topic; default the one the stored checksum names, else the only one.

    Raises:
        BagError: on the first problem, naming bag, topic and position.
        DecodeError: for an event message that does not decode (naming bag, topic, position).
    """
    from hrn_vo_ros.core.events.arrays import EventChecksum

    path = Path(path)
    meta = custom_data(path)
    notes: list[str] = []
    counts: dict[str, int] = {}
    with open_bag(path) as reader:
        storage = bag_storage(path) if path.is_dir() else (
            'mcap' if path.suffix == '.mcap' else 'sqlite3')
        facts = check_storage(path, reader, storage, full=True)
        for m in iter_messages(reader):
            counts[m.topic] = counts.get(m.topic, 0) + 1
        want = {c.topic: c.msgcount for c in reader.connections}
        event_topics = sorted({c.topic for c in reader.connections
                               if c.msgtype in (EVENT_PACKET, DVS_EVENT_ARRAY)})
    if path.is_dir():
        for name, n in want.items():
            if counts.get(name, 0) != n:
                raise IntegrityError(f'{path}: topic {name}: read {counts.get(name, 0)} '
                                     f'messages, the metadata says {n}: the bag is corrupt or '
                                     'truncated')
    topic = topic or meta.get(TOPIC_KEY) or (event_topics[0] if len(event_topics) == 1
                                             else None)
    checksum: str | None = None
    n_events = 0
    if topic is not None:
        ck = EventChecksum()
        for ev in iter_bag_events(path, topic=topic):
            ck.update(ev)
        checksum, n_events = ck.hexdigest(), ck.count
    else:
        notes.append('no single event topic: events not decoded')
    stored = meta.get(CHECKSUM_KEY)
    if stored is not None and topic == meta.get(TOPIC_KEY, topic):
        if stored != checksum:
            raise IntegrityError(f'{path}: topic {topic}: the events decode to checksum '
                                 f'{checksum} ({n_events} events) but the bag was written with '
                                 f'{stored} ({meta.get(COUNT_KEY, "?")} events): the bag is '
                                 'corrupt')
    else:
        notes.append('no stored event checksum (not written by hrn-vo convert)')
    n_crc = sum(1 for s in facts.scans for c in s.chunks if c.stored_crc)
    if storage == 'mcap' and facts.scans and n_crc == 0:
        notes.append('the MCAP chunks carry no CRCs (written by another tool)')
    return BagVerification(path, storage, counts, topic, n_events, checksum, stored, n_crc,
                           tuple(notes))
