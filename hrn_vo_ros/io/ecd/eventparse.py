"""Fast parsing of ``events.txt`` (``t x y p`` per line), streamed from a folder or a zip.

A vectorised path parses the dataset's strict layout (single spaces, the same number of
decimals on every line) with no per-line Python; anything else (tabs, blank lines, ``#``
comments, varying decimals) goes through a per-line path that also names the first bad line.
Times are parsed from the decimal text as integers, never through float seconds.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.ecd.source import (
    EVENTS_FILE,
    meta_count,
    META_FILE,
    read_all,
    read_meta,
    SequenceSource,
    source_sensor_size,
)
from hrn_vo_ros.io.ecd.times import format_ns, MAX_SECONDS, NS_PER_S, seconds_to_ns

_CHUNK_BYTES = 4 << 20  # text parsed at a time: cache-friendly (about 200k lines)
_MAX_FIELD = 10**9  # larger x, y, p tokens are corrupt (and would overflow int64 arrays)


def iter_events(path: Path | str, *, chunk_events: int = 1_000_000,
                sensor_size: tuple[int, int] | None = None) -> Iterator[EventArray]:
    """Stream ``events.txt`` of a sequence folder or zip as batches of events.

    Args:
        path: The sequence folder or its ``.zip``.
        chunk_events: Largest batch size; batches follow line boundaries and vary in size
            (the parser reads 4 MB of text at a time, so batches stay below ~200k events).
        sensor_size: (width, height) to check coordinates against; default from
            :func:`read_sensor_size`.

    Yields:
        Batches in file order (times non-decreasing across batches).

    Raises:
        DatasetError: naming file and line for a malformed line, wrong column count, unsorted
            times, a coordinate outside the sensor, a polarity not 0/1, a truncated file.
    """
    if chunk_events < 1:
        raise DatasetError(f'chunk_events={chunk_events} must be >= 1')
    with SequenceSource(path) as src:
        meta = read_meta(src)
        width, height = sensor_size if sensor_size is not None else source_sensor_size(src)
        expected = meta_count(meta, 'events')
        where = src.where(EVENTS_FILE)
        chunk_bytes = max(1 << 16, min(chunk_events * 18, _CHUNK_BYTES))
        parser = _EventParser(where, width, height)
        with src.open(EVENTS_FILE) as f:
            rest = b''
            while True:
                data = read_all(f, where, chunk_bytes)
                if not data:
                    break
                buf = rest + data
                cut = buf.rfind(b'\n') + 1
                rest = buf[cut:]
                if cut:
                    yield from _split(parser.parse(buf[:cut]), chunk_events)
            if rest.strip():
                yield from _split(parser.parse(rest + b'\n', last=True), chunk_events)
        if expected is not None and parser.count != expected:
            msg = (f'has {parser.count} events but {META_FILE} records {expected}: the file is '
                   'truncated or was edited; write the sequence again')
            raise DatasetError(msg, path=where)


def _split(ev: EventArray, n: int) -> Iterator[EventArray]:
    for i in range(0, len(ev), n):
        yield ev[i:i + n] if len(ev) > n else ev


class _EventParser:
    """Parses whole-line chunks of ``events.txt``; keeps line numbers and time order across
    chunks. A vectorised path handles the dataset's strict layout; anything else (tabs, blank
    lines, CRLF, varying decimals) goes through a per-line path that also pinpoints errors."""

    def __init__(self, where: Path, width: int, height: int) -> None:
        self.where = where
        self.width = width
        self.height = height
        self.line = 1      # 1-based number of the next chunk's first line
        self.count = 0
        self.last_t = np.int64(-1)

    def parse(self, buf: bytes, *, last: bool = False) -> EventArray:
        n_lines = buf.count(b'\n')
        fast = _parse_fast(buf, n_lines)
        if fast is not None:
            t, x, y, p = fast
            line_of = None
        else:
            t, x, y, p, line_of = _parse_slow(buf, self.line, self.where, last=last)
        self._check(t, x, y, p, line_of)
        self.line += n_lines
        self.count += t.size
        if t.size:
            self.last_t = t[-1]
        return EventArray.from_arrays(t, x, y, p)

    def _lineno(self, i: int, line_of: NDArray[np.int64] | None) -> int:
        return int(line_of[i]) if line_of is not None else self.line + i

    def _check(self, t: NDArray[np.int64], x: NDArray[np.int64], y: NDArray[np.int64],
               p: NDArray[np.int64], line_of: NDArray[np.int64] | None) -> None:
        if t.size == 0:
            return
        bad = np.flatnonzero((x < 0) | (x >= self.width) | (y < 0) | (y >= self.height))
        if bad.size:
            i = int(bad[0])
            msg = (f'event at x={x[i]}, y={y[i]} is outside the {self.width}x{self.height} '
                   'sensor: a corrupt line, or give the right sensor size (meta.json; '
                   'hrn-vo convert --sensor-size WxH)')
            raise DatasetError(msg, path=self.where, line=self._lineno(i, line_of))
        bad = np.flatnonzero((p != 0) & (p != 1))
        if bad.size:
            i = int(bad[0])
            raise DatasetError(f'polarity {p[i]} must be 0 (OFF) or 1 (ON)', path=self.where,
                               line=self._lineno(i, line_of))
        if t[0] < self.last_t:
            raise DatasetError(f'time {format_ns(int(t[0]))} s is before the previous line '
                               f'({format_ns(int(self.last_t))} s): events must be sorted by time',
                               path=self.where, line=self._lineno(0, line_of))
        bad = np.flatnonzero(t[1:] < t[:-1])
        if bad.size:
            i = int(bad[0]) + 1
            raise DatasetError(f'time {format_ns(int(t[i]))} s is before the previous line '
                               f'({format_ns(int(t[i - 1]))} s): events must be sorted by time',
                               path=self.where, line=self._lineno(i, line_of))


_I64 = NDArray[np.int64]


_U64 = np.uint64
_ASCII_ZEROS = _U64(0x3030303030303030)
_HIGH_NIBBLES = _U64(0xF0F0F0F0F0F0F0F0)
_PAD = 16  # bytes of b'\n' before a chunk: every token has 16 readable bytes before its end


def _swar_digits(u64: NDArray[np.uint64], end: _I64, width: _I64,
                 ) -> tuple[_I64, NDArray[np.bool_]]:
    """Values of the decimal tokens of 1..8 digits that end (exclusive) at byte ``end``.

    SIMD-within-a-register: the 8 bytes before ``end`` are read as one little-endian uint64
    (``u64[i]`` = bytes ``i..i+7``), the bytes before the token are set to ``'0'``, and three
    multiply-shift-mask steps combine digit pairs, quads and octets. Also returns which tokens
    hold a non-digit byte.

    Shapes:
        end, width: (n,) -> values (n,) int64, bad (n,) bool.
    """
    v = u64[end - 8]
    keep = ~((_U64(1) << ((8 - width) * 8).astype(np.uint64)) - _U64(1))
    v = (v & keep) | (_ASCII_ZEROS & ~keep)
    bad = (((v & _HIGH_NIBBLES) != _ASCII_ZEROS)
           | (((v + _U64(0x0606060606060606)) & _HIGH_NIBBLES) != _ASCII_ZEROS))
    v = v - _ASCII_ZEROS
    v = (v * _U64(10) + (v >> _U64(8))) & _U64(0x00FF00FF00FF00FF)
    v = (v * _U64(100) + (v >> _U64(16))) & _U64(0x0000FFFF0000FFFF)
    v = (v * _U64(10000) + (v >> _U64(32))) & _U64(0x00000000FFFFFFFF)
    return v.astype(np.int64), bad


def _parse_fast(buf: bytes, n: int) -> tuple[_I64, _I64, _I64, _I64] | None:
    """Vectorised parse of lines ``S.F X Y P`` (single spaces, same decimals on every line).

    Finds every separator with one comparison per byte, checks that each line has exactly the
    layout, then converts all tokens at once with :func:`_swar_digits` (no float, no per-line
    Python). Returns None when the chunk does not have exactly that layout (the caller then
    parses it line by line, which accepts other whitespace and reports the first bad line).
    """
    if n == 0:
        return None
    padded = b'\n' * _PAD + buf
    arr = np.frombuffer(padded, np.uint8)
    u64 = np.ndarray(shape=(len(padded) - 7,), dtype='<u8', buffer=padded, strides=(1,))
    nl = np.flatnonzero(arr == 10)[_PAD:]
    dots = np.flatnonzero(arr == 46)
    sp = np.flatnonzero(arr == 32)
    if nl.size != n or dots.size != n or sp.size != 3 * n:
        return None
    s3 = sp.reshape(n, 3)
    starts = np.empty(n, np.int64)
    starts[0] = _PAD
    starts[1:] = nl[:-1] + 1
    w = int(s3[0, 0] - dots[0] - 1)  # decimals of the first line
    if not 1 <= w <= 9:
        return None
    wsec, wx, wy = dots - starts, s3[:, 1] - s3[:, 0] - 1, s3[:, 2] - s3[:, 1] - 1
    layout_ok = bool(np.all((wsec >= 1) & (wsec <= 10) & (s3[:, 0] - dots == w + 1)
                            & (wx >= 1) & (wx <= 5) & (wy >= 1) & (wy <= 5)
                            & ((nl - s3[:, 2] == 2)
                               | ((nl - s3[:, 2] == 3) & (arr[nl - 1] == 13)))))  # LF or CRLF
    if not layout_ok:
        return None
    sec, bad = _swar_digits(u64, dots, np.minimum(wsec, 8))
    long_sec = wsec > 8  # e.g. epoch stamps: 9-10 digits of seconds
    if np.any(long_sec):
        hi, bad_hi = _swar_digits(u64, dots - 8, np.clip(wsec - 8, 1, 8))
        sec = np.where(long_sec, hi * 100_000_000 + sec, sec)
        bad |= (long_sec & bad_hi) | (sec > MAX_SECONDS)  # int64 ns would overflow
    wf = min(w, 8)
    frac, bad_f = _swar_digits(u64, s3[:, 0], np.full(n, wf, np.int64))
    bad |= bad_f
    if w == 9:
        d0 = arr[dots + 1].astype(np.int64) - 48
        bad |= (d0 < 0) | (d0 > 9)
        frac += d0 * 100_000_000
    x, bad_x = _swar_digits(u64, s3[:, 1], wx)
    y, bad_y = _swar_digits(u64, s3[:, 2], wy)
    p = arr[s3[:, 2] + 1].astype(np.int64) - 48
    if np.any(bad | bad_x | bad_y):
        return None
    t = sec * NS_PER_S + frac * 10 ** (9 - w)
    return t, x, y, p


def _parse_slow(buf: bytes, first_line: int, where: Path, *,
                last: bool) -> tuple[_I64, _I64, _I64, _I64, _I64]:
    """Line-by-line parse: any whitespace, blank and ``#`` lines skipped, exact errors."""
    lines = buf.split(b'\n')[:-1]
    out = np.empty((len(lines), 4), np.int64)
    line_of = np.empty(len(lines), np.int64)
    k = 0
    for i, raw in enumerate(lines):
        lineno = first_line + i
        parts = raw.split()
        if not parts or parts[0].startswith(b'#'):
            continue
        truncated = last and i == len(lines) - 1
        if len(parts) != 4:
            hint = (' (the file looks truncated: its last line is incomplete)' if truncated
                    else '')
            msg = f'expected 4 columns "t x y p", got {len(parts)}: {_show(raw)}{hint}'
            raise DatasetError(msg, path=where, line=lineno)
        try:
            t = seconds_to_ns(parts[0].decode('ascii'))
            x, y, p = int(parts[1]), int(parts[2]), int(parts[3])
        except (ValueError, UnicodeDecodeError) as err:
            hint = ' (the file looks truncated)' if truncated else ''
            msg = f'malformed event line {_show(raw)}: {err}{hint}'
            raise DatasetError(msg, path=where, line=lineno) from None
        if not (abs(x) <= _MAX_FIELD and abs(y) <= _MAX_FIELD and abs(p) <= _MAX_FIELD):
            msg = (f'event line {_show(raw)} has a coordinate or polarity of more than '
                   f'{len(str(_MAX_FIELD))} digits: a corrupt line (x, y are sensor pixels, '
                   'p is 0 or 1)')
            raise DatasetError(msg, path=where, line=lineno)
        out[k] = (t, x, y, p)
        line_of[k] = lineno
        k += 1
    return out[:k, 0], out[:k, 1], out[:k, 2], out[:k, 3], line_of[:k]


def _show(raw: bytes) -> str:
    text = raw.decode('ascii', 'replace').rstrip('\r')
    return repr(text if len(text) <= 60 else text[:57] + '...')


def read_events(path: Path | str, *, sensor_size: tuple[int, int] | None = None) -> EventArray:
    """All events of a sequence in memory (see :func:`iter_events`; fine for small data)."""
    return EventArray.concatenate(list(iter_events(path, sensor_size=sensor_size)))
