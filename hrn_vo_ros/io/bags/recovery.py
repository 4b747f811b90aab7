"""Salvage of an interrupted MCAP recording: its complete chunks rewritten as a finished bag."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
import os
from pathlib import Path
import struct
import zlib

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2.storage_mcap import get_qos
from rosbags.typesys.store import Typestore

from hrn_vo_ros.errors import BagError
from hrn_vo_ros.io.bags.mcap import (
    _mcap_fail,
    _mcap_string,
    _OP_CHANNEL,
    _OP_CHUNK,
    _OP_DATA_END,
    _OP_FOOTER,
    MCAP_MAGIC,
)
from hrn_vo_ros.io.bags.reading import _partial_root
from hrn_vo_ros.io.bags.types import RELIABLE_QOS, typestore
from hrn_vo_ros.io.bags.writing import BagWriter

_OP_SCHEMA, _OP_MESSAGE = 0x03, 0x05
RECOVERED_KEY = 'hrn_vo_ros.recovered_from'
"""``custom_data`` key of a recovered bag: the ``.partial`` storage file it was salvaged from."""


@dataclass(frozen=True, slots=True)
class Recovery:
    """What :func:`recover_bag` salvaged: the new bag, its messages and what was left out."""

    dst: Path
    sources: tuple[Path, ...]
    counts: dict[str, int]
    chunks: int
    start_ns: int | None
    end_ns: int | None
    dropped_bytes: int
    stop_reason: str


def _chunk_records(records: memoryview) -> Iterator[tuple[int, memoryview]]:
    """``(opcode, body)`` of the records inside one chunk.

    Raises:
        ValueError: if a record runs past the end of the chunk.
    """
    off, end = 0, len(records)
    while off < end:
        if off + 9 > end:
            raise ValueError(f'record header cut off at chunk byte {off}')
        op, n = struct.unpack_from('<BQ', records, off)
        if n > end - off - 9:
            raise ValueError(f'record at chunk byte {off} runs past the chunk')
        yield op, records[off + 9:off + 9 + n]
        off += 9 + n


def _chunk_payload(body: bytes) -> tuple[int, memoryview]:
    """``(stored CRC, uncompressed records)`` of a chunk record's body.

    Raises:
        ValueError: for a chunk that is compressed or whose sizes disagree.
    """
    if len(body) < 40:
        raise ValueError('chunk record too short')
    _t0, _t1, usize, stored, clen_comp = struct.unpack_from('<QQQII', body, 0)
    comp = bytes(body[32:32 + clen_comp])
    off = 32 + clen_comp
    if off + 8 > len(body):
        raise ValueError('chunk record too short')
    (clen,) = struct.unpack_from('<Q', body, off)
    records = memoryview(body)[off + 8:off + 8 + clen]
    if comp or len(records) != clen or clen != usize:
        raise ValueError(f'chunk compression {comp!r} or sizes {clen}/{usize} not salvageable')
    return stored, records


def _salvageable(path: Path) -> tuple[list[tuple[int, int]], int, str]:
    """The complete chunks of an unfinished MCAP file.

    Returns:
        ``([(offset, length), ...], bytes not salvaged, why the scan stopped)``; the scan stops
        at the first record that is cut off, damaged (structure or CRC) or starts the summary.

    Raises:
        BagError: if the file is not an MCAP file at all.
    """
    chunks: list[tuple[int, int]] = []
    with path.open('rb') as f:
        size = f.seek(0, os.SEEK_END)
        f.seek(0)
        if f.read(8) != MCAP_MAGIC:
            raise _mcap_fail(path, 0, 'no MCAP magic at the start')
        pos, good = 8, 8
        reason = 'end of file'
        while pos < size:
            head = f.read(9)
            if len(head) < 9:
                reason = f'record header cut off at byte {pos}'
                break
            op, length = struct.unpack('<BQ', head)
            if length > size - pos - 9:
                reason = (f'record at byte {pos} cut off ({size - pos - 9} of {length} bytes '
                          'written)')
                break
            if op in (_OP_DATA_END, _OP_FOOTER):
                reason = 'summary reached (the file was finished)'
                good = size
                break
            if op == _OP_CHUNK:
                body = f.read(length)
                try:
                    stored, records = _chunk_payload(body)
                    if stored and stored != zlib.crc32(records):
                        raise ValueError('CRC mismatch')
                    for _ in _chunk_records(records):
                        pass
                except ValueError as err:
                    reason = f'chunk at byte {pos} damaged ({err})'
                    break
                chunks.append((pos, length))
            else:
                f.seek(length, os.SEEK_CUR)
            pos += 9 + length
            good = pos
    return chunks, size - good, reason


def _recover_sources(partial: Path) -> list[Path]:
    if partial.is_file():
        return [partial]
    files = sorted(partial.rglob('*.mcap'))
    if not files:
        what = ('only sqlite3 (.db3) files: rosbags commits sqlite3 rows when the bag is '
                'closed, so nothing can be salvaged' if any(partial.rglob('*.db3'))
                else 'no .mcap file')
        raise BagError(f'{partial}: {what}; record with storage mcap to make recordings '
                       'recoverable')
    return files


def recover_bag(partial: Path | str, dst: Path | str | None = None) -> Recovery:
    """Rewrite what an interrupted MCAP recording wrote, up to its last complete chunk, as a bag.

    A killed writer (SIGKILL, a crash) leaves ``NAME.partial/NAME/NAME.mcap`` without its
    summary or ``metadata.yaml``. Every chunk record that is complete (and whose CRC, when
    stored, matches) holds whole messages, with the schema and channel records in the first
    chunk; they are written again, in file order, to a new bag through :class:`BagWriter`
    (chunk, data and summary CRCs, statistics, ``metadata.yaml`` with the recorded QoS, and
    ``custom_data`` :data:`RECOVERED_KEY`). The ``.partial`` directory itself is left as it was.

    Args:
        partial: The ``.partial`` directory (or the ``.mcap`` file inside it).
        dst: The bag to create; default ``NAME`` beside ``NAME.partial``.

    Raises:
        BagError: if there is nothing to salvage, ``dst`` exists or the data is inconsistent.
    """
    partial = Path(partial)
    if not partial.exists():
        raise BagError(f'{partial} does not exist: give the .partial directory a recording left')
    root = _partial_root(partial.resolve())
    if dst is None:
        if not root.name.endswith('.partial'):
            raise BagError(f'{partial} is not inside a ".partial" directory: name the output bag')
        dst = root.with_name(root.name[:-len('.partial')])
    dst = Path(dst)
    sources = _recover_sources(partial.resolve())
    plans = [(src, *_salvageable(src)) for src in sources]
    if not any(chunks for _, chunks, _, _ in plans):
        why = '; '.join(f'{src.name}: {reason}' for src, _, _, reason in plans)
        raise BagError(f'{partial}: no complete chunk to salvage ({why}): the writer was stopped '
                       'before its first chunk was written')
    staging = dst.with_name(dst.name + '.partial')
    moved: Path | None = None
    if staging.resolve() == root:  # BagWriter stages in NAME.partial: move the source aside
        moved = root.with_name(root.name + '.recovering')
        if moved.exists():
            raise BagError(f'{moved} exists (an earlier recovery was interrupted): rename it back '
                           f'to {root.name} and retry')
        if dst.exists():
            raise BagError(f'{dst} exists already: choose another output or delete it')
        os.rename(root, moved)
        sources = [moved / s.relative_to(root) for s in sources]
        plans = [(s, *p[1:]) for s, p in zip(sources, plans, strict=True)]
    try:
        return _rewrite(partial, dst, plans)
    finally:
        if moved is not None:
            os.rename(moved, root)


def _rewrite(partial: Path, dst: Path,
             plans: list[tuple[Path, list[tuple[int, int]], int, str]]) -> Recovery:
    ts = typestore()
    counts: dict[str, int] = {}
    t0: int | None = None
    t1: int | None = None
    n_chunks = dropped = 0
    reasons: list[str] = []
    with BagWriter(dst) as w:
        for src, chunks, lost, reason in plans:
            schemas: dict[int, str] = {}
            channels: dict[int, tuple[str, str, list[Qos]]] = {}
            conns: dict[int, Connection] = {}
            with src.open('rb') as f:
                for pos, length in chunks:
                    f.seek(pos + 9)
                    _, records = _chunk_payload(f.read(length))
                    for op, body in _chunk_records(records):
                        if op == _OP_SCHEMA:
                            (sid,) = struct.unpack_from('<H', body, 0)
                            schemas[sid], _ = _mcap_string(bytes(body), 2, src, pos)
                        elif op == _OP_CHANNEL:
                            cid, sid = struct.unpack_from('<HH', body, 0)
                            topic, off = _mcap_string(bytes(body), 4, src, pos)
                            _enc, off = _mcap_string(bytes(body), off, src, pos)
                            (mlen,) = struct.unpack_from('<I', body, off)
                            qos = get_qos(bytes(body[off + 4:off + 4 + mlen]))
                            if sid not in schemas:
                                raise BagError(f'{src}: chunk at byte {pos}: channel {topic} '
                                               f'names schema {sid}, which no record defines')
                            channels[cid] = (topic, schemas[sid], qos)
                        elif op == _OP_MESSAGE:
                            cid, _seq, log_ns = struct.unpack_from('<HIQ', body, 0)
                            if cid not in conns:
                                conns[cid] = _recovered_topic(w, ts, src, pos, cid, channels)
                            w.write(conns[cid], log_ns, bytes(body[22:]))
                            topic = conns[cid].topic
                            counts[topic] = counts.get(topic, 0) + 1
                            t0 = log_ns if t0 is None else min(t0, log_ns)
                            t1 = log_ns if t1 is None else max(t1, log_ns)
                    n_chunks += 1
            dropped += lost
            reasons.append(f'{src.name}: {reason}')
        w.set_custom_data(RECOVERED_KEY, str(partial))
    return Recovery(dst, tuple(p[0] for p in plans), counts, n_chunks, t0, t1, dropped,
                    '; '.join(reasons))


def _recovered_topic(w: BagWriter, ts: Typestore, src: Path, pos: int, cid: int,
                     channels: dict[int, tuple[str, str, list[Qos]]]) -> Connection:
    if cid not in channels:
        raise BagError(f'{src}: chunk at byte {pos}: a message on channel {cid}, which no '
                       'channel record defines: the file is damaged')
    topic, msgtype, qos = channels[cid]
    if msgtype not in ts.types:
        raise BagError(f'{src}: topic {topic} has type {msgtype}, which this package does not '
                       'know: it cannot be rewritten')
    return w.add_topic(topic, msgtype, qos[0] if qos else RELIABLE_QOS)
