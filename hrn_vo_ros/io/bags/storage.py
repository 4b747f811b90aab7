"""What the storage files hold (counts, bag-time range, CRCs) against what metadata.yaml says."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import sqlite3

from rosbags.rosbag2 import Reader
import yaml

from hrn_vo_ros.errors import BagError, IntegrityError
from hrn_vo_ros.io.bags.mcap import check_mcap_crcs, McapScan, scan_mcap

MAX_BAG_SPAN_NS = 7 * 24 * 3600 * 1_000_000_000
"""Longest bag-time span :func:`open_bag` accepts (7 days): longer ones hold a stray stamp."""


def _storage_files(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    try:
        doc = yaml.safe_load((path / 'metadata.yaml').read_text())
        files = doc['rosbag2_bagfile_information'].get('relative_file_paths') or []
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError) as err:
        raise BagError(f'{path / "metadata.yaml"}: unreadable bag metadata ({err})') from err
    return [path / str(f) for f in files]


def _sqlite_stats(db: Path) -> tuple[dict[str, int], int | None, int | None, str]:
    """Messages per topic, first and last bag time and ``PRAGMA quick_check`` of a .db3 file."""
    try:
        con = sqlite3.connect(f'file:{db}?mode=ro', uri=True)
        try:
            rows = con.execute('SELECT t.name, COUNT(m.id), MIN(m.timestamp), '
                               'MAX(m.timestamp) FROM messages m JOIN topics t ON '
                               't.id = m.topic_id GROUP BY t.name').fetchall()
            check = str(con.execute('PRAGMA quick_check').fetchone()[0])
        finally:
            con.close()
    except sqlite3.Error as err:
        raise BagError(f'{db}: not a readable rosbag2 sqlite3 file ({err}): corrupt; convert '
                       'it again') from err
    counts = {str(r[0]): int(r[1]) for r in rows}
    t0 = min((int(r[2]) for r in rows), default=None)
    t1 = max((int(r[3]) for r in rows), default=None)
    return counts, t0, t1, check


@dataclass(frozen=True, slots=True)
class StorageFacts:
    """What the storage files say, independent of metadata.yaml."""

    counts: dict[str, int] | None
    start_ns: int | None
    end_ns: int | None
    scans: list[McapScan]


def storage_facts(path: Path | str, storage: str, *, full: bool = False) -> StorageFacts:
    """Per-topic message counts and bag-time range read from the storage files themselves.

    MCAP: from the statistics and channel records (and every CRC, see :func:`scan_mcap`);
    sqlite3: by counting the rows. Counts are None when an MCAP file has no statistics.
    ``full`` reads every MCAP record (all CRCs, see :func:`scan_mcap`), else only the summary.

    Raises:
        BagError: for unreadable or structurally broken storage files.
    """
    path = Path(path)
    counts: dict[str, int] | None = {}
    t0s: list[int] = []
    t1s: list[int] = []
    scans: list[McapScan] = []
    for f in _storage_files(path):
        if storage == 'mcap':
            scan = scan_mcap(f, full=full)
            scans.append(scan)
            part = scan.topic_counts()
            if scan.start_ns is not None and scan.end_ns is not None and part:
                t0s.append(scan.start_ns)
                t1s.append(scan.end_ns)
        elif storage == 'sqlite3':
            part, a, b, check = _sqlite_stats(f)
            if check != 'ok':
                raise BagError(f'{f}: sqlite integrity check failed ({check[:200]}): the bag '
                               'is corrupt; convert or copy it again')
            if a is not None and b is not None:
                t0s.append(a)
                t1s.append(b)
        else:
            return StorageFacts(None, None, None, [])
        if part is None or counts is None:
            counts = None
        else:
            for k, v in part.items():
                counts[k] = counts.get(k, 0) + v
    return StorageFacts(counts, min(t0s, default=None), max(t1s, default=None), scans)


def check_storage(path: Path | str, reader: Reader, storage: str, *,
                  full: bool = False) -> StorageFacts:
    """Compare metadata.yaml with the storage files and refuse absurd bag-time spans.

    Raises:
        BagError: when a topic's ``message_count`` in the metadata differs from the storage,
            when a CRC fails (MCAP), or when the bag spans more than :data:`MAX_BAG_SPAN_NS`.
    """
    path = Path(path)
    facts = storage_facts(path, storage, full=full)
    for scan in facts.scans:
        check_mcap_crcs(scan)
    if facts.counts is not None and path.is_dir():
        meta = {c.topic: c.msgcount for c in reader.connections}
        for topic in sorted(set(meta) | set(facts.counts)):
            want, got = meta.get(topic, 0), facts.counts.get(topic, 0)
            if want != got:
                raise IntegrityError(f'{path / "metadata.yaml"}: topic {topic} has '
                                     f'message_count {want} but the storage holds {got} '
                                     'messages: the metadata was edited or belongs to another '
                                     f'bag; set it to {got} (or run `ros2 bag reindex`)')
        total = int(reader.message_count)
        if total != sum(facts.counts.values()):
            raise BagError(f'{path / "metadata.yaml"}: message_count {total} but the topics '
                           f'hold {sum(facts.counts.values())} messages: set it to the sum')
    if facts.start_ns is not None and facts.end_ns is not None:
        _check_span(path, facts.start_ns, facts.end_ns)
    if int(reader.message_count):
        _check_span(path, int(reader.start_time), int(reader.end_time) - 1)
    return facts


def _check_span(path: Path, t0: int, t1: int) -> None:
    if t1 - t0 > MAX_BAG_SPAN_NS:
        raise BagError(f'{path}: bag time runs from {t0} to {t1} ns, a span of '
                       f'{(t1 - t0) / 86400e9:.1f} days (more than '
                       f'{MAX_BAG_SPAN_NS / 86400e9:.0f}): some messages carry a stamp from '
                       'another clock (e.g. 0 or wall time); fix their stamps or split the bag')
