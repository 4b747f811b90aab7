"""MCAP structure: a record walk that computes (and can fill in) every CRC the format defines."""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import struct
from typing import Any, IO
import zlib

from hrn_vo_ros.errors import BagError, IntegrityError

MCAP_MAGIC = b'\x89MCAP0\r\n'
_OP_FOOTER, _OP_CHANNEL, _OP_CHUNK, _OP_STATISTICS, _OP_DATA_END = 0x02, 0x04, 0x06, 0x0B, 0x0F


@dataclass(frozen=True, slots=True)
class McapChunk:
    """One MCAP chunk record: byte offset of its opcode, stored CRC and the CRC of its records."""

    offset: int
    start_ns: int
    end_ns: int
    stored_crc: int
    crc: int


@dataclass(frozen=True, slots=True)
class McapScan:
    """What :func:`scan_mcap` found in an MCAP file (everything a CRC covers, and the counts)."""

    path: Path
    chunks: list[McapChunk]
    data_crc_stored: int
    data_crc: int
    summary_crc_stored: int
    summary_crc: int
    topics: dict[int, str]
    counts: dict[int, int] | None
    start_ns: int | None
    end_ns: int | None

    def bad_chunk(self) -> McapChunk | None:
        """The first chunk whose stored (non-zero) CRC does not match its records."""
        return next((c for c in self.chunks if c.stored_crc and c.stored_crc != c.crc), None)

    def topic_counts(self) -> dict[str, int] | None:
        """Messages per topic from the statistics record (None without one)."""
        if self.counts is None:
            return None
        out: dict[str, int] = {}
        for cid, n in self.counts.items():
            name = self.topics.get(cid, f'channel {cid}')
            out[name] = out.get(name, 0) + n
        return out


def _mcap_fail(path: Path, offset: int, what: str) -> BagError:
    return BagError(f'{path}: byte {offset}: {what}: the MCAP file is truncated or corrupt; '
                    'record or convert the bag again')


def _u(fmt: str, buf: bytes, off: int, path: Path, at: int) -> tuple[Any, ...]:
    try:
        return struct.unpack_from(fmt, buf, off)
    except struct.error:
        raise _mcap_fail(path, at, 'record too short for its fields') from None


def _mcap_string(buf: bytes, off: int, path: Path, at: int) -> tuple[str, int]:
    (n,) = _u('<I', buf, off, path, at)
    if off + 4 + n > len(buf):
        raise _mcap_fail(path, at, 'string longer than its record')
    return bytes(buf[off + 4:off + 4 + n]).decode('utf-8', 'replace'), off + 4 + n


def scan_mcap(path: Path | str, *, full: bool = True, patch: bool = False) -> McapScan:
    """Walk every record of an MCAP file, computing the CRCs the format defines.

    Chunk CRC: CRC-32 of the chunk's uncompressed records. Data-section CRC: CRC-32 of every
    byte from the start of the file up to the DataEnd record. Summary CRC: CRC-32 from the
    summary start through the footer's ``summary_offset_start`` field. A stored value of 0
    means "not computed". With ``patch`` the computed values are written into the file (what
    :class:`BagWriter` does after rosbags, which writes zeros). Without ``full`` only the
    summary section is read (channels, statistics, summary CRC; chunks are left unchecked:
    rosbags checks each chunk's CRC when it reads it).

    Raises:
        BagError: for a file that is not a structurally valid MCAP file, naming the offset.
    """
    path = Path(path)
    mode = 'r+b' if patch else 'rb'
    try:
        f = path.open(mode)
    except OSError as err:
        raise BagError(f'{path}: cannot read ({err})') from err
    with f:
        return _McapScanner(path, f, patch=patch).scan(full=full)


class _McapScanner:
    """The state of one :func:`scan_mcap` walk over an open MCAP file."""

    def __init__(self, path: Path, f: IO[bytes], *, patch: bool) -> None:
        self.path, self.f, self.patch = path, f, patch
        self.chunks: list[McapChunk] = []
        self.topics: dict[int, str] = {}
        self.counts: dict[int, int] | None = None
        self.start_ns: int | None = None
        self.end_ns: int | None = None
        self.data_crc_stored = self.summary_crc_stored = self.summary_crc = 0
        self.data_crc: int | None = None
        self.summary_start: int | None = None
        self.running = 0

    def scan(self, *, full: bool) -> McapScan:
        """Check both magics and walk the records (from the summary only without ``full``)."""
        f, path = self.f, self.path
        size = f.seek(0, os.SEEK_END)
        f.seek(0)
        if size < 2 * len(MCAP_MAGIC) or f.read(8) != MCAP_MAGIC:
            raise _mcap_fail(path, 0, 'no MCAP magic at the start')
        self.running = zlib.crc32(MCAP_MAGIC)
        pos = 8
        if not full and not self.patch:
            pos = self._seek_summary(size, pos)
        pos = self._walk(size, pos)
        if f.read(8) != MCAP_MAGIC:
            raise _mcap_fail(path, pos, 'no MCAP magic at the end')
        if self.data_crc is None or self.summary_start is None:
            raise _mcap_fail(path, pos, 'no DataEnd record')
        return McapScan(path, self.chunks, self.data_crc_stored, self.data_crc,
                        self.summary_crc_stored, self.summary_crc, self.topics, self.counts,
                        self.start_ns, self.end_ns)

    def _seek_summary(self, size: int, pos: int) -> int:
        """Position the walk at the summary the footer names (the data section is not read)."""
        f, path = self.f, self.path
        f.seek(size - 8 - 29)
        tail = f.read(29)
        if tail[0] != _OP_FOOTER:
            raise _mcap_fail(path, size - 37, 'no footer record')
        s_start = struct.unpack_from('<Q', tail, 9)[0]
        if s_start:
            if not 8 <= s_start <= size - 37:
                raise _mcap_fail(path, size - 37, f'summary start {s_start} out of range')
            pos = self.summary_start = s_start
            self.data_crc = 0  # the data section is not read
            f.seek(pos)
        return pos

    def _walk(self, size: int, pos: int) -> int:
        """Read records from ``pos`` through the footer; the position after the footer."""
        f, path = self.f, self.path
        while pos < size - 8:
            head = f.read(9)
            if len(head) < 9:
                raise _mcap_fail(path, pos, 'record header cut off')
            op, length = struct.unpack('<BQ', head)
            if length > size - pos - 9:
                raise _mcap_fail(path, pos, f'record of {length} bytes runs past the end')
            body = f.read(length)
            if op == _OP_CHUNK:
                body = self._chunk(pos, length, body)
            elif op == _OP_DATA_END:
                self._data_end(pos, length, body)
            elif op == _OP_CHANNEL:
                (cid,) = _u('<H', body, 0, path, pos)
                self.topics[cid], _ = _mcap_string(body, 4, path, pos)
            elif op == _OP_STATISTICS:
                self._statistics(pos, body)
            elif op == _OP_FOOTER:
                self._footer(pos, length, body)
                pos += 9 + length
                return pos
            if self.data_crc is None:
                self.running = zlib.crc32(head + body, self.running)
            pos += 9 + length
        raise _mcap_fail(path, pos, 'no footer record')

    def _chunk(self, pos: int, length: int, body: bytes) -> bytes:
        """Record a chunk and its CRC (patched into the file with ``patch``); the body as now."""
        f, path = self.f, self.path
        t0, t1, usize, stored = _u('<QQQI', body, 0, path, pos)
        comp, off = _mcap_string(body, 28, path, pos)
        (clen,) = _u('<Q', body, off, path, pos)
        records = body[off + 8:off + 8 + clen]
        if comp or len(records) != clen or clen != usize:
            raise _mcap_fail(path, pos, f'chunk compression {comp!r} or sizes '
                             f'{clen}/{usize} not readable here')
        crc = zlib.crc32(records)
        if self.patch and stored != crc:
            body = body[:24] + struct.pack('<I', crc) + body[28:]
            f.seek(pos + 9 + 24)
            f.write(struct.pack('<I', crc))
            f.seek(pos + 9 + length)
            stored = crc
        self.chunks.append(McapChunk(pos, t0, t1, stored, crc))
        return body

    def _data_end(self, pos: int, length: int, body: bytes) -> None:
        """Take the data-section CRC so far (patched into the DataEnd record with ``patch``)."""
        f = self.f
        self.data_crc = self.running
        (self.data_crc_stored,) = _u('<I', body, 0, self.path, pos)
        if self.patch:
            f.seek(pos + 9)
            f.write(struct.pack('<I', self.running))
            f.seek(pos + 9 + length)
            self.data_crc_stored = self.running
        self.summary_start = pos + 9 + length

    def _statistics(self, pos: int, body: bytes) -> None:
        """Take the per-channel message counts and the bag-time range of a Statistics record."""
        path = self.path
        (_n, _s, _c, _a, _m, _k, t0, t1, mlen) = _u('<QHIIIIQQI', body, 0, path, pos)
        counts: dict[int, int] = {}
        self.counts = counts
        for i in range(mlen // 10):
            cid, n = _u('<HQ', body, 46 + 10 * i, path, pos)
            counts[cid] = n
        self.start_ns, self.end_ns = t0, t1

    def _footer(self, pos: int, length: int, body: bytes) -> None:
        """Compute the summary CRC the footer covers (patched into it with ``patch``)."""
        f = self.f
        s_start, _s_off, self.summary_crc_stored = _u('<QQI', body, 0, self.path, pos)
        f.seek(s_start if s_start else pos)
        covered = f.read(pos + 9 + 16 - (s_start if s_start else pos))
        self.summary_crc = zlib.crc32(covered)
        if self.patch and s_start:
            f.seek(pos + 9 + 16)
            f.write(struct.pack('<I', self.summary_crc))
            self.summary_crc_stored = self.summary_crc
        f.seek(pos + 9 + length)


def check_mcap_crcs(scan: McapScan) -> None:
    """Refuse an MCAP file whose stored (non-zero) CRCs do not match its bytes.

    Raises:
        BagError: naming the file, the byte offset and the bag-time range of a bad chunk.
    """
    bad = scan.bad_chunk()
    if bad is not None:
        raise IntegrityError(f'{scan.path}: the chunk at byte {bad.offset} (bag time '
                             f'{bad.start_ns}..{bad.end_ns} ns) fails its CRC (stored '
                             f'{bad.stored_crc:08x}, computed {bad.crc:08x}): the bag is '
                             'corrupt; convert or copy it again')
    if scan.data_crc_stored and scan.data_crc_stored != scan.data_crc:
        raise IntegrityError(f'{scan.path}: the data section fails its CRC (stored '
                             f'{scan.data_crc_stored:08x}, computed {scan.data_crc:08x}): bytes '
                             'outside the chunks (message indexes) are corrupt; convert it again')
    if scan.summary_crc_stored and scan.summary_crc_stored != scan.summary_crc:
        raise IntegrityError(f'{scan.path}: the summary section fails its CRC (stored '
                             f'{scan.summary_crc_stored:08x}, computed '
                             f'{scan.summary_crc:08x}): the index at the end of the file is '
                             'corrupt; convert it again')
