"""The Event Camera Dataset text layout (Mueggler et al., IJRR 2017): read fast, write atomically.

A sequence is a folder (or a ``.zip`` of it, members at the root or under one top folder) with

* ``events.txt``: ``t x y p`` per line, ``t`` in seconds with a fixed number of decimals
  (9 in the dataset, so that int64 ns round-trip exactly), ``p`` 1 = ON, 0 = OFF;
* ``imu.txt``: ``t ax ay az gx gy gz`` (m/s^2, rad/s);
* ``groundtruth.txt``: ``t px py pz qx qy qz qw`` (metres, camera-to-world quaternion x y z w);
* ``calib.txt``: ``fx fy cx cy k1 k2 p1 p2 k3`` on one line;
* optional ``images.txt`` and ``images/`` (ignored here).

The dataset has no sensor-size file (all sequences are DAVIS240C, 240 x 180). Folders written by
:func:`write_sequence` carry an extra ``meta.json`` (``{"format": "hrn_vo_ecd/1", "width",
"height", "counts": {"events", "imu", "groundtruth"}}``); readers use it when present (sensor size,
and line counts that reveal a file truncated at a line boundary) and fall back to 240 x 180.

Public API:

* :func:`write_sequence(folder, seq) <write_sequence>`: writes a
  :class:`~hrn_vo_ros.core.events.sequence.Sequence`; refuses to overwrite; writes into a hidden
  ``.<name>.partial-*`` folder first and renames it, so an interrupted write never looks complete.
* :func:`iter_events(path, *, chunk_events=1_000_000) <iter_events>` ->
  ``Iterator[EventArray]``: streaming event reader for a folder or its zip (streamed from the
  member, no extraction); batches of at most ``chunk_events`` (and ~200k); memory stays bounded
  (tens of MB) whatever the file size.
* :func:`read_events`, :func:`read_imu`, :func:`read_groundtruth`, :func:`read_calib`,
  :func:`read_sensor_size`, :func:`read_sequence` (everything, in memory), :func:`events_size`
  (bytes of ``events.txt``, for progress bars), :func:`event_count` (from ``meta.json`` or None),
  :func:`estimate_event_count` (exact from ``meta.json``, else from the file size),
  :func:`format_events` (``events.txt`` lines of a batch, vectorised).

Measured (bench/bench_convert.py, 7 M lines, 2 shared cores): parsing 5-8 M lines/s, writing
~1.3-2 M lines/s; a 60 s sequence (23 M lines, 500 MB) streams with 85 MB peak RSS.

Times are parsed from the decimal text as integers (seconds and fraction digits separately),
never through float seconds, so nanosecond stamps are exact. Every bad input raises
:class:`~hrn_vo_ros.errors.DatasetError` naming the file and the 1-based line: a missing file, a
malformed line or wrong column count, unsorted timestamps, coordinates outside the sensor, a
polarity other than 0/1, a truncated file.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
import functools
import json
import os
from pathlib import Path
import shutil
import tempfile
from typing import IO
import warnings
import zipfile

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import CameraCalibration, ImuData, Sequence, Trajectory
from hrn_vo_ros.errors import DatasetError

DEFAULT_SENSOR_SIZE = (240, 180)
"""(width, height) of the DAVIS240C used by every Event Camera Dataset sequence."""

META_FILE = 'meta.json'
META_FORMAT = 'hrn_vo_ecd/1'
EVENTS_FILE = 'events.txt'
IMU_FILE = 'imu.txt'
GROUNDTRUTH_FILE = 'groundtruth.txt'
CALIB_FILE = 'calib.txt'

_NS_PER_S = 1_000_000_000
_MAX_SECONDS = 9_000_000_000  # int64 ns overflow guard (~285 years)
_WRITE_CHUNK = 500_000
_CHUNK_BYTES = 4 << 20  # text parsed at a time: cache-friendly (about 200k lines)


# ------------------------------------------------------------------------------------ sources

class _Source:
    """A sequence folder or zip: opens members by name and names them in error messages."""

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        if '.partial' in self.path.name:
            msg = ('is an unfinished write (".partial" in its name): an interrupted writer left '
                   'it; delete it and write the sequence again')
            raise DatasetError(msg, path=self.path)
        self._zip: zipfile.ZipFile | None = None
        self._prefix = ''
        if self.path.is_dir():
            return
        if not self.path.exists():
            raise DatasetError('does not exist: give an Event Camera Dataset folder or its .zip',
                               path=self.path)
        if not zipfile.is_zipfile(self.path):
            msg = 'is neither a folder nor a zip file (corrupt or truncated zip?)'
            raise DatasetError(msg, path=self.path)
        try:
            self._zip = zipfile.ZipFile(self.path)
        except (zipfile.BadZipFile, OSError) as err:
            raise DatasetError(f'cannot open zip: {err}', path=self.path) from err
        names = set(self._zip.namelist())
        if EVENTS_FILE not in names:
            tops = {n.split('/', 1)[0] for n in names if n.count('/') >= 1}
            hits = [t for t in sorted(tops) if f'{t}/{EVENTS_FILE}' in names]
            if len(hits) == 1:
                self._prefix = hits[0] + '/'

    def where(self, name: str) -> Path:
        """The path to name in messages (``seq.zip/events.txt`` for zip members)."""
        return self.path / (self._prefix + name)

    def exists(self, name: str) -> bool:
        if self._zip is None:
            return (self.path / name).is_file()
        try:
            self._zip.getinfo(self._prefix + name)
        except KeyError:
            return False
        return True

    def size(self, name: str) -> int:
        if self._zip is None:
            return (self.path / name).stat().st_size
        return self._zip.getinfo(self._prefix + name).file_size

    @contextmanager
    def open(self, name: str) -> Iterator[IO[bytes]]:
        """The member as a binary stream; a missing member raises DatasetError."""
        if not self.exists(name):
            raise DatasetError(f'missing {name} (an Event Camera Dataset sequence has events.txt, '
                               'imu.txt, groundtruth.txt and calib.txt)', path=self.where(name))
        if self._zip is None:
            with open(self.path / name, 'rb') as f:
                yield f
        else:
            with self._zip.open(self._prefix + name) as f:
                yield f

    def read_text(self, name: str) -> str:
        with self.open(name) as f:
            data = _read_all(f, self.where(name))
        try:
            return data.decode('ascii')
        except UnicodeDecodeError as err:
            raise DatasetError(f'not ASCII text (byte {err.start}): is this the right file?',
                               path=self.where(name)) from err

    def close(self) -> None:
        if self._zip is not None:
            self._zip.close()

    def __enter__(self) -> _Source:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _read_all(f: IO[bytes], where: Path, size: int = -1) -> bytes:
    try:
        return f.read(size)
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as err:
        raise DatasetError(f'cannot read (corrupt or truncated archive?): {err}',
                           path=where) from err


def _read_meta(src: _Source) -> dict[str, object]:
    if not src.exists(META_FILE):
        return {}
    try:
        meta = json.loads(src.read_text(META_FILE))
    except json.JSONDecodeError as err:
        raise DatasetError(f'invalid JSON: {err}', path=src.where(META_FILE)) from err
    if not isinstance(meta, dict) or meta.get('format') != META_FORMAT:
        raise DatasetError(f'not a {META_FORMAT} metadata file', path=src.where(META_FILE))
    return meta


def _meta_count(meta: dict[str, object], key: str) -> int | None:
    counts = meta.get('counts')
    if isinstance(counts, dict) and isinstance(counts.get(key), int):
        return int(counts[key])
    return None


# ------------------------------------------------------------------------------------ readers

def read_sensor_size(path: Path | str) -> tuple[int, int]:
    """The sensor (width, height): from ``meta.json`` if present, else 240 x 180 (DAVIS240C)."""
    with _Source(path) as src:
        return _sensor_size(src)


def _sensor_size(src: _Source) -> tuple[int, int]:
    meta = _read_meta(src)
    if not meta:
        return DEFAULT_SENSOR_SIZE
    w, h = meta.get('width'), meta.get('height')
    if not (isinstance(w, int) and isinstance(h, int) and 0 < w <= 65535 and 0 < h <= 65535):
        raise DatasetError(f'width/height {w!r}/{h!r} must be integers in 1..65535',
                           path=src.where(META_FILE))
    return w, h


def event_count(path: Path | str) -> int | None:
    """The number of events recorded in ``meta.json``, or None (plain dataset folders)."""
    with _Source(path) as src:
        return _meta_count(_read_meta(src), 'events')


def estimate_event_count(path: Path | str) -> int:
    """The event count from ``meta.json``, else estimated from the size of ``events.txt`` and
    the mean line length of its first 256 kB (for progress bars on plain dataset folders)."""
    with _Source(path) as src:
        exact = _meta_count(_read_meta(src), 'events')
        if exact is not None:
            return exact
        if not src.exists(EVENTS_FILE):
            raise DatasetError(f'missing {EVENTS_FILE}', path=src.where(EVENTS_FILE))
        with src.open(EVENTS_FILE) as f:
            head = _read_all(f, src.where(EVENTS_FILE), 1 << 18)
        lines = max(head.count(b'\n'), 1)
        return round(src.size(EVENTS_FILE) * lines / max(len(head), 1))


def events_size(path: Path | str) -> int:
    """Size of ``events.txt`` in bytes (uncompressed), e.g. as a progress-bar total."""
    with _Source(path) as src:
        if not src.exists(EVENTS_FILE):
            raise DatasetError(f'missing {EVENTS_FILE}', path=src.where(EVENTS_FILE))
        return src.size(EVENTS_FILE)


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
    with _Source(path) as src:
        meta = _read_meta(src)
        width, height = sensor_size if sensor_size is not None else _sensor_size(src)
        expected = _meta_count(meta, 'events')
        where = src.where(EVENTS_FILE)
        chunk_bytes = max(1 << 16, min(chunk_events * 18, _CHUNK_BYTES))
        parser = _EventParser(where, width, height)
        with src.open(EVENTS_FILE) as f:
            rest = b''
            while True:
                data = _read_all(f, where, chunk_bytes)
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
            raise DatasetError(f'time {_fmt_ns(int(t[0]))} s is before the previous line '
                               f'({_fmt_ns(int(self.last_t))} s): events must be sorted by time',
                               path=self.where, line=self._lineno(0, line_of))
        bad = np.flatnonzero(t[1:] < t[:-1])
        if bad.size:
            i = int(bad[0]) + 1
            raise DatasetError(f'time {_fmt_ns(int(t[i]))} s is before the previous line '
                               f'({_fmt_ns(int(t[i - 1]))} s): events must be sorted by time',
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
        bad |= (long_sec & bad_hi) | (sec > _MAX_SECONDS)  # int64 ns would overflow
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
    t = sec * _NS_PER_S + frac * 10 ** (9 - w)
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
        out[k] = (t, x, y, p)
        line_of[k] = lineno
        k += 1
    return out[:k, 0], out[:k, 1], out[:k, 2], out[:k, 3], line_of[:k]


def _show(raw: bytes) -> str:
    text = raw.decode('ascii', 'replace').rstrip('\r')
    return repr(text if len(text) <= 60 else text[:57] + '...')


def seconds_to_ns(tok: str) -> int:
    """Exact int ns from a decimal seconds string (``12.000001234``, ``3``, ``0.5``).

    The one seconds-text parser of the I/O layer (dataset, estimate and trajectory files).

    Raises:
        ValueError: for anything but digits with at most 9 decimals, or an int64 overflow.
    """
    sec, dot, frac = tok.partition('.')
    if not (sec.isascii() and sec.isdigit()) or (frac and not (frac.isascii()
                                                                and frac.isdigit())):
        raise ValueError(f'time {tok!r} is not a non-negative decimal number of seconds')
    if len(frac) > 9:
        raise ValueError(f'time {tok!r} has more than 9 decimals (finer than 1 ns)')
    if int(sec) > _MAX_SECONDS:
        raise ValueError(f'time {tok!r} is too large')
    return int(sec) * _NS_PER_S + (int(frac.ljust(9, '0')) if frac else 0)


def _fmt_ns(t: int) -> str:
    return f'{t // _NS_PER_S}.{t % _NS_PER_S:09d}' if t >= 0 else f'-{_fmt_ns(-t)}'


def read_events(path: Path | str, *, sensor_size: tuple[int, int] | None = None) -> EventArray:
    """All events of a sequence in memory (see :func:`iter_events`; fine for small data)."""
    return EventArray.concatenate(list(iter_events(path, sensor_size=sensor_size)))


def _read_table(src: _Source, name: str, columns: str,
                ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """A small ``t v1 v2 ...`` text table of a sequence (see :func:`parse_table`)."""
    return parse_table(src.read_text(name), columns, src.where(name))


def parse_table(text: str, columns: str, where: Path | str, *,
                to_ns: Callable[[str], int] = seconds_to_ns,
                ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """A ``t v1 v2 ...`` text table: exact int ns times (decimal seconds) and float values.

    Blank lines and ``#`` comments are skipped; the times must not decrease.

    Args:
        text: The table.
        columns: Column names, space separated (``'t px py pz qx qy qz qw'``), for messages.
        where: File named in the errors.
        to_ns: Time token → int ns (default exact decimal seconds).

    Raises:
        DatasetError: naming the line for a wrong column count, a bad or non-finite number or a
            time before the previous line.

    Shapes:
        returns t (n,) int64 and values (n, ncol - 1) float64.
    """
    ncol = len(columns.split())
    fast = _table_fast(text, ncol) if to_ns is seconds_to_ns else None
    if fast is not None:
        return fast
    lines = text.split('\n')
    ts: list[int] = []
    rows: list[list[float]] = []
    for i, line in enumerate(lines):
        parts = line.split()
        if not parts or parts[0].startswith('#'):
            continue
        if len(parts) != ncol:
            hint = (' (the file looks truncated: its last line is incomplete)'
                    if i == len(lines) - 1 else '')
            msg = f'expected {ncol} columns "{columns}", got {len(parts)}: {line[:60]!r}{hint}'
            raise DatasetError(msg, path=where, line=i + 1)
        try:
            t = to_ns(parts[0])
            vals = [float(v) for v in parts[1:]]
        except ValueError as err:
            raise DatasetError(f'malformed line {line[:60]!r}: {err}', path=where,
                               line=i + 1) from None
        if not all(np.isfinite(vals)):
            raise DatasetError(f'non-finite value in {line[:60]!r}', path=where, line=i + 1)
        if ts and t < ts[-1]:
            raise DatasetError(f'time {parts[0]} s is before the previous line: lines must be '
                               'sorted by time', path=where, line=i + 1)
        ts.append(t)
        rows.append(vals)
    t_arr = np.array(ts, dtype=np.int64)
    v_arr = np.array(rows, dtype=np.float64).reshape(len(rows), ncol - 1)
    return t_arr, v_arr


def _table_fast(text: str, ncol: int,
                ) -> tuple[NDArray[np.int64], NDArray[np.float64]] | None:
    """Whole-table parse (numpy for the values, exact integer times), or None when anything is
    unusual (comments, blank lines, a bad value), so that the per-line parser names the line."""
    lines = text.splitlines()
    if not lines or '#' in text or not all(lines):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        try:
            vals = np.fromstring(text, dtype=np.float64, sep=' ')
        except (DeprecationWarning, ValueError):
            return None
    if vals.size != len(lines) * ncol or not np.all(np.isfinite(vals)):
        return None
    try:
        t = np.array([seconds_to_ns(line.split(None, 1)[0]) for line in lines], np.int64)
    except ValueError:
        return None
    if np.any(t[1:] < t[:-1]):
        return None
    return t, np.ascontiguousarray(vals.reshape(len(lines), ncol)[:, 1:])


def _check_count(src: _Source, name: str, key: str, n: int) -> None:
    expected = _meta_count(_read_meta(src), key)
    if expected is not None and expected != n:
        raise DatasetError(f'has {n} lines but {META_FILE} records {expected}: the file is '
                           'truncated or was edited', path=src.where(name))


def read_imu(path: Path | str) -> ImuData:
    """``imu.txt`` (``t ax ay az gx gy gz``) of a sequence folder or zip."""
    with _Source(path) as src:
        t, v = _read_table(src, IMU_FILE, 't ax ay az gx gy gz')
        _check_count(src, IMU_FILE, 'imu', t.size)
    return ImuData(t=t, acc=np.ascontiguousarray(v[:, :3]), gyro=np.ascontiguousarray(v[:, 3:]))


def read_groundtruth(path: Path | str) -> Trajectory:
    """``groundtruth.txt`` (``t px py pz qx qy qz qw``) of a sequence folder or zip."""
    with _Source(path) as src:
        t, v = _read_table(src, GROUNDTRUTH_FILE, 't px py pz qx qy qz qw')
        _check_count(src, GROUNDTRUTH_FILE, 'groundtruth', t.size)
    return Trajectory(t=t, pos=np.ascontiguousarray(v[:, :3]),
                      quat=np.ascontiguousarray(v[:, 3:]))


def read_calib(path: Path | str) -> CameraCalibration:
    """``calib.txt`` (``fx fy cx cy k1 k2 p1 p2 k3``) plus the sensor size."""
    with _Source(path) as src:
        width, height = _sensor_size(src)
        where = src.where(CALIB_FILE)
        lines = [ln for ln in src.read_text(CALIB_FILE).split('\n') if ln.strip()]
        if len(lines) != 1:
            raise DatasetError(f'expected one line "fx fy cx cy k1 k2 p1 p2 k3", got '
                               f'{len(lines)} non-empty lines', path=where)
        parts = lines[0].split()
        if len(parts) not in (4, 8, 9):
            raise DatasetError(f'expected 9 numbers "fx fy cx cy k1 k2 p1 p2 k3" (or 4 without '
                               f'distortion), got {len(parts)}', path=where, line=1)
        try:
            vals = [float(v) for v in parts]
        except ValueError as err:
            raise DatasetError(f'malformed calibration: {err}', path=where, line=1) from None
    dist = tuple(vals[4:] + [0.0] * (9 - len(vals)))
    return CameraCalibration(width=width, height=height, fx=vals[0], fy=vals[1], cx=vals[2],
                             cy=vals[3], dist=(dist[0], dist[1], dist[2], dist[3], dist[4]))


def read_sequence(path: Path | str) -> Sequence:
    """A whole sequence in memory; ``imu``/``groundtruth`` are None when their file is absent."""
    with _Source(path) as src:
        has_imu, has_gt = src.exists(IMU_FILE), src.exists(GROUNDTRUTH_FILE)
    return Sequence(events=read_events(path), calib=read_calib(path),
                    imu=read_imu(path) if has_imu else None,
                    groundtruth=read_groundtruth(path) if has_gt else None)


# ------------------------------------------------------------------------------------ writer

def write_sequence(folder: Path | str, seq: Sequence) -> Path:
    """Write ``seq`` in the Event Camera Dataset text layout plus ``meta.json``.

    Files: ``events.txt`` (9 decimals: exact ns), ``calib.txt``, ``meta.json``, and
    ``imu.txt``/``groundtruth.txt`` when present. Floats use the shortest exact representation,
    so a read gives back identical values.

    Args:
        folder: The new sequence folder; must not exist.
        seq: The sequence (times int64 ns >= 0, sorted).

    Returns:
        ``folder`` as a Path.

    Raises:
        DatasetError: if ``folder`` exists, or the data cannot be written as a valid sequence
            (negative or unsorted times, events outside the sensor).
    """
    folder = Path(folder)
    if folder.exists() or folder.is_symlink():
        raise DatasetError('already exists: choose a new folder or delete the old one',
                           path=folder)
    _validate_for_write(seq)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f'.{folder.name}.partial-', dir=folder.parent))
    try:
        with open(tmp / EVENTS_FILE, 'wb') as f:
            ev = seq.events
            for i in range(0, len(ev), _WRITE_CHUNK):
                f.write(format_events(ev[i:i + _WRITE_CHUNK]))
        c = seq.calib
        calib_vals = (c.fx, c.fy, c.cx, c.cy, *c.dist)
        (tmp / CALIB_FILE).write_text(' '.join(repr(float(v)) for v in calib_vals) + '\n')
        counts = {'events': len(ev)}
        if seq.imu is not None:
            _write_table(tmp / IMU_FILE, seq.imu.t, np.hstack([seq.imu.acc, seq.imu.gyro]))
            counts['imu'] = len(seq.imu)
        if seq.groundtruth is not None:
            gt = seq.groundtruth
            _write_table(tmp / GROUNDTRUTH_FILE, gt.t, np.hstack([gt.pos, gt.quat]))
            counts['groundtruth'] = len(gt)
        meta = {'format': META_FORMAT, 'width': c.width, 'height': c.height, 'counts': counts}
        (tmp / META_FILE).write_text(json.dumps(meta, indent=1) + '\n')
        for p in tmp.iterdir():
            _fsync(p)
        os.chmod(tmp, 0o755)
        if folder.exists():
            raise DatasetError('appeared while writing: not overwriting it', path=folder)
        os.rename(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def _fsync(path: Path) -> None:
    with open(path, 'rb') as f:
        os.fsync(f.fileno())


def _validate_for_write(seq: Sequence) -> None:
    ev, c = seq.events, seq.calib
    if len(ev):
        if ev.t[0] < 0:
            raise DatasetError('event times must be >= 0 ns to be written as events.txt')
        if np.any(ev.t[1:] < ev.t[:-1]):
            raise DatasetError('events must be sorted by time')
        if int(ev.x.max()) >= c.width or int(ev.y.max()) >= c.height:
            raise DatasetError(f'events lie outside the {c.width}x{c.height} sensor of the '
                               'calibration')
        if int(ev.p.max()) > 1:
            raise DatasetError('polarities must be 0 or 1')
    for name, t in (('imu', None if seq.imu is None else seq.imu.t),
                    ('groundtruth', None if seq.groundtruth is None else seq.groundtruth.t)):
        if t is not None and t.size and (t[0] < 0 or np.any(t[1:] < t[:-1])):
            raise DatasetError(f'{name} times must be >= 0 and sorted')


def _write_table(path: Path, t: NDArray[np.int64], values: NDArray[np.float64]) -> None:
    with open(path, 'w') as f:
        for ti, row in zip(t.tolist(), values.tolist(), strict=True):
            f.write(_fmt_ns(ti) + ' ' + ' '.join(repr(v) for v in row) + '\n')


@functools.cache
def _digit_table() -> tuple[NDArray[np.uint8], NDArray[np.int64]]:
    """ASCII digits (zero-padded to 5) and digit counts of 0..65535.

    Shapes:
        (65536, 5) uint8 and (65536,) int64.
    """
    v = np.arange(65536, dtype=np.int64)
    return _digits_div(v, 5), _ndigits(v, 5)


def _digits_div(v: NDArray[np.int64], width: int) -> NDArray[np.uint8]:
    pow10 = 10 ** np.arange(width - 1, -1, -1, dtype=np.int64)
    return ((v[:, None] // pow10) % 10 + 48).astype(np.uint8)


def _digits(v: NDArray[np.int64], width: int) -> NDArray[np.uint8]:
    """ASCII digits of non-negative ints, zero-padded to ``width``, by table look-up of groups of
    four digits (values up to 10^width - 1).

    Shapes:
        v: (n,) -> (n, width) uint8.
    """
    table = _digit_table()[0]
    out = np.empty((v.shape[0], width), np.uint8)
    end = width
    while end > 0:
        k = min(4, end)
        group = (v // 10 ** (width - end)) % 10 ** k
        out[:, end - k:end] = table[group][:, 5 - k:]
        end -= k
    return out


def _ndigits(v: NDArray[np.int64], width: int) -> NDArray[np.int64]:
    nd = np.ones(v.shape, np.int64)
    for k in range(1, width):
        nd += v >= 10 ** k
    return nd


def format_events(ev: EventArray) -> bytes:
    """``events.txt`` lines (``S.FFFFFFFFF X Y P``) for a batch, vectorised (no per-line Python).

    Builds one fixed-width byte row per event (digits by table look-up) and drops the leading
    zeros of the variable-width fields with a mask.
    """
    n = len(ev)
    if n == 0:
        return b''
    table, counts = _digit_table()
    t = ev.t.astype(np.int64)
    sec, frac = t // _NS_PER_S, t % _NS_PER_S
    ws = len(str(int(sec.max())))
    width = ws + 1 + 9 + 1 + 5 + 1 + 5 + 1 + 1 + 1
    rows = np.empty((n, width), np.uint8)
    keep = np.ones((n, width), bool)
    cols = np.arange(5)[None, :]
    rows[:, :ws] = _digits(sec, ws)
    keep[:, :ws] = np.arange(ws)[None, :] >= (ws - _ndigits(sec, ws))[:, None]
    c = ws
    rows[:, c] = ord('.')
    rows[:, c + 1:c + 10] = _digits(frac, 9)
    c += 10
    for coord in (ev.x, ev.y):
        rows[:, c] = ord(' ')
        rows[:, c + 1:c + 6] = table[coord]
        keep[:, c + 1:c + 6] = cols >= (5 - counts[coord])[:, None]
        c += 6
    rows[:, c] = ord(' ')
    rows[:, c + 1] = ev.p + 48
    rows[:, c + 2] = ord('\n')
    return rows[keep].tobytes()
