"""Writing a sequence in the Event Camera Dataset text layout, atomically, and the vectorised
``events.txt`` formatter."""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path
import shutil
import tempfile

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import Sequence
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.ecd.source import (
    CALIB_FILE,
    EVENTS_FILE,
    GROUNDTRUTH_FILE,
    IMU_FILE,
    META_FILE,
    META_FORMAT,
)
from hrn_vo_ros.io.ecd.times import format_ns, NS_PER_S

_WRITE_CHUNK = 500_000


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
            f.write(format_ns(ti) + ' ' + ' '.join(repr(v) for v in row) + '\n')


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
    sec, frac = t // NS_PER_S, t % NS_PER_S
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
