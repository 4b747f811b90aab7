"""Reading bags: open (metadata versions 5 to 9, storage inference, no half bags), iterate."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.interfaces import Connection
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.reader import DirectoryReader
import yaml

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import BagError, DecodeError
from hrn_vo_ros.io import eventpacket
from hrn_vo_ros.io.bags.mcap import scan_mcap
from hrn_vo_ros.io.bags.storage import check_storage
from hrn_vo_ros.io.bags.types import DVS_EVENT_ARRAY, EVENT_PACKET, typestore

METADATA_VERSIONS = range(5, 10)
"""rosbag2 metadata versions :func:`open_bag` reads (5: Foxy/Galactic ... 9: Jazzy)."""
STORAGE_SUFFIXES = {'.mcap': 'mcap', '.db3': 'sqlite3'}
"""Storage identifier of each storage file suffix, for metadata that leaves it empty."""


def _check_bag_path(path: Path) -> None:
    if any(part.endswith('.partial') for part in path.resolve().parts):
        raise BagError(f'{path} is an unfinished bag (".partial"): an interrupted write left '
                       'it. From a conversion: delete it and convert again. From a recording '
                       f'(bag_recorder): `hrn-vo recover {_partial_root(path)}` rewrites what it '
                       'wrote up to its last complete chunk as a bag')
    if not path.exists():
        raise BagError(f'{path} does not exist: give a ROS 2 bag directory')
    if path.is_dir() and not (path / 'metadata.yaml').is_file():
        raise BagError(f'{path} has no metadata.yaml: not a complete ROS 2 bag directory')


def _partial_root(path: Path) -> Path:
    """The ``*.partial`` directory a path lies in (the path itself when none is)."""
    for p in (path, *path.parents):
        if p.name.endswith('.partial'):
            return p
    return path


def bag_storage(path: Path | str) -> str:
    """The storage identifier of a bag directory (``'mcap'`` or ``'sqlite3'``).

    It is the metadata's ``storage_identifier``, or, when that is empty or missing, the one
    the storage files' suffixes name.

    Raises:
        BagError: on unreadable metadata, a metadata version outside 5 to 9, or storage files
            of no or mixed known kinds.
    """
    meta_path = Path(path) / 'metadata.yaml'
    try:
        doc = yaml.safe_load(meta_path.read_text())
        info = doc['rosbag2_bagfile_information']
        version = int(info['version'])
        files = [str(f) for f in info.get('relative_file_paths') or []]
        storage = str(info.get('storage_identifier') or '')
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as err:
        raise BagError(f'{meta_path}: unreadable bag metadata ({type(err).__name__}: {err})'
                       ) from err
    if version not in METADATA_VERSIONS:
        raise BagError(f'{meta_path}: rosbag2 metadata version {version}; this reader opens '
                       f'versions {METADATA_VERSIONS[0]} to {METADATA_VERSIONS[-1]}')
    if storage:
        return storage
    kinds = {STORAGE_SUFFIXES.get(Path(f).suffix) for f in files}
    if len(kinds) != 1 or None in kinds:
        raise BagError(f'{meta_path}: empty storage_identifier and storage files '
                       f'{files or "(none)"} are not all .mcap or all .db3: cannot tell the '
                       'storage')
    return str(kinds.pop())


class BagReader(Reader):
    """A rosbags ``Reader`` that :func:`open_bag` has opened already.

    Use it with ``with`` (closes on exit) or call :meth:`close` yourself.
    """

    def __enter__(self) -> BagReader:
        return self


def open_bag(path: Path | str) -> BagReader:
    """A ROS 2 bag opened for reading: ``with open_bag(path) as reader: ...``.

    Args:
        path: A bag directory (metadata versions 5 to 9, see :func:`bag_storage`) or a single
            ``.mcap`` / ``.db3`` storage file.

    Raises:
        BagError: for ``.partial`` paths, missing, incomplete or corrupt bags, unsupported
            metadata versions or storages.
    """
    path = Path(path)
    _check_bag_path(path)
    try:
        reader = BagReader(path)
    except Exception as err:
        raise BagError(f'{path}: not a ROS 2 bag ({type(err).__name__}: {err})') from err
    if path.is_dir() and isinstance(reader.storage, DirectoryReader):
        storage = bag_storage(path)
        plugins = DirectoryReader.STORAGE_PLUGINS
        if storage not in plugins:
            raise BagError(f'{path}: storage {storage!r} is not supported; use a bag stored as '
                           f'{" or ".join(plugins)}')
        # rosbags looks the metadata's storage_identifier up in this table: an empty one
        # resolves to the storage the files name
        reader.storage.STORAGE_PLUGINS = {**plugins, '': plugins[storage]}
    try:
        reader.open()
    except Exception as err:  # rosbags raises its own errors and sqlite/mcap ones
        raise BagError(f'{path}: cannot read the bag ({type(err).__name__}: {err})') from err
    try:
        storage = bag_storage(path) if path.is_dir() else STORAGE_SUFFIXES.get(path.suffix, '')
        check_storage(path, reader, storage)
    except BaseException:
        reader.close()
        raise
    return reader


@dataclass(frozen=True, slots=True)
class BagMessage:
    """One raw record: topic, type, bag time (ns), CDR bytes and the recorded QoS profiles."""

    topic: str
    msgtype: str
    t_ns: int
    raw: bytes | memoryview
    connection: Connection


def iter_messages(reader: Reader, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Raw records in bag-time order, optionally only ``topics``.

    Raises:
        BagError: when a record cannot be read (corrupt bag), naming the bag.
    """
    conns = [c for c in reader.connections if topics is None or c.topic in topics]
    it = reader.messages(connections=conns)
    k, last = 0, None
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except Exception as err:
            names = ', '.join(sorted({c.topic for c in conns})) or 'no topic'
            where = (f'after record {k} (bag time {last} ns)' if last is not None
                     else 'at the first record')
            raise BagError(f'{reader.path}: topics {names}: corrupt record {where}'
                           f'{_locate_corruption(Path(str(reader.path)))} ({type(err).__name__}: '
                           f'{err}): the bag is damaged; convert or copy it again') from err
        conn, t, raw = item
        k, last = k + 1, t
        yield BagMessage(conn.topic, conn.msgtype, t, raw, conn)


def _locate_corruption(path: Path) -> str:
    """Where an MCAP bag's first bad chunk lies (``''`` when that cannot be told)."""
    files = [path] if path.suffix == '.mcap' else sorted(path.glob('*.mcap'))
    for f in files:
        try:
            bad = scan_mcap(f).bad_chunk()
        except BagError as err:
            return f'; {err}'
        if bad is not None:
            return (f'; {f.name}: the chunk at byte {bad.offset} (bag time {bad.start_ns}..'
                    f'{bad.end_ns} ns) fails its CRC')
    return ''


def iter_bag_events(path: Path | str, *, topic: str | None = None) -> Iterator[EventArray]:
    """Decoded events of one event topic of a ROS 2 bag, one batch per message.

    Args:
        path: The bag directory (or file).
        topic: The topic; default the only EventPacket or dvs EventArray topic.

    Raises:
        BagError: if there is no (or more than one candidate) event topic or a record is corrupt.
        DecodeError: on an unknown encoding or a corrupt payload.
    """
    ts = typestore()
    with open_bag(path) as reader:
        conns = [c for c in reader.connections
                 if c.msgtype in (EVENT_PACKET, DVS_EVENT_ARRAY)
                 and (topic is None or c.topic == topic)]
        topics = sorted({c.topic for c in conns})
        if len(topics) != 1:
            found = ', '.join(topics) or 'none'
            raise BagError(f'{path}: need exactly one event topic (EventPacket or dvs '
                           f'EventArray){" named " + topic if topic else ""}; found {found}')
        decoder: eventpacket.PacketDecoder | None = None
        for k, m in enumerate(iter_messages(reader, topics)):
            where = f'{path}: {m.topic}: message {k} (bag time {m.t_ns} ns)'
            if m.msgtype == DVS_EVENT_ARRAY:
                try:
                    yield eventpacket.decode_dvs_cdr(m.raw).events
                except DecodeError as err:
                    raise DecodeError(f'{where}: {err}') from err
                continue
            try:
                msg: Any = ts.deserialize_cdr(m.raw, EVENT_PACKET)
            except Exception as err:
                raise DecodeError(f'{where}: corrupt EventPacket ({type(err).__name__}: '
                                  f'{err})') from err
            if decoder is None:  # evt3: drop out-of-sensor events, as the C++ decoder does
                decoder = eventpacket.PacketDecoder(width=int(msg.width) or None,
                                                    height=int(msg.height) or None)
            try:
                ev = decoder.decode(str(msg.encoding), msg.events, time_base=int(msg.time_base),
                                    is_bigendian=bool(msg.is_bigendian))
                if msg.encoding == 'mono':
                    check_packet_events(ev, int(msg.width), int(msg.height))
            except DecodeError as err:
                raise DecodeError(f'{where}: {err}') from err
            yield ev


def check_packet_events(ev: EventArray, width: int, height: int) -> None:
    """Refuse a decoded stateless packet whose events are off the sensor or out of time order.

    Stateless encodings (``mono``) keep every word, so an event outside the packet's
    ``width`` x ``height`` (when given) or a time before the previous event's means a corrupt
    payload (a bit flip that no storage checksum caught).

    Raises:
        DecodeError: naming the first bad event.
    """
    if len(ev) == 0:
        return
    bad = np.zeros(len(ev), bool)
    if width:
        bad |= ev.x >= width
    if height:
        bad |= ev.y >= height
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise DecodeError(f'event {i} at x={int(ev.x[i])}, y={int(ev.y[i])} is outside the '
                          f'{width}x{height} sensor the packet names: a corrupt payload')
    back = np.flatnonzero(ev.t[1:] < ev.t[:-1])
    if back.size:
        i = int(back[0]) + 1
        raise DecodeError(f'event {i} at {int(ev.t[i])} ns is before event {i - 1} '
                          f'({int(ev.t[i - 1])} ns): times must not decrease within a packet; '
                          'a corrupt payload')
