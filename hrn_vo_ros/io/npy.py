"""Event arrays saved as NumPy files (robot-arm style recordings) and their trajectory files.

Accepted event files:

* ``.npy`` with a structured dtype holding fields ``t, x, y, p`` (any order and integer widths;
  e.g. Metavision's ``EventCD`` ``x u2, y u2, p i2, t i8`` in microseconds), memory-mapped and
  streamed in batches;
* ``.npy`` of shape (n, 4) with columns ``t, x, y, p``;
* ``.npz`` with arrays ``t, x, y, p``.

Times are converted from ``time_unit`` (``'us'`` by default, as Metavision stores them; ``'s'``,
``'ms'``, ``'ns'`` also) to int64 ns; float times are rounded to the nearest ns. Polarity ``p > 0``
is ON. A trajectory file is TUM-like text, ``t px py pz qx qy qz qw`` per line (seconds; spaces or
commas; ``#`` comments), the same layout as the Event Camera Dataset's ``groundtruth.txt``.

Public API: :func:`iter_npy_events`, :func:`npy_event_count`, :func:`read_trajectory`.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import Trajectory
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.ecd import parse_table, seconds_to_ns

TimeUnit = Literal['s', 'ms', 'us', 'ns']
_NS_PER = {'s': 1_000_000_000, 'ms': 1_000_000, 'us': 1_000, 'ns': 1}


def _columns(path: Path) -> tuple[NDArray[np.generic], ...]:
    """(t, x, y, p) arrays (memory-mapped for .npy) of an event file: 1-D, of one length."""
    cols = _raw_columns(path)
    shapes = [c.shape for c in cols]
    if any(len(s) != 1 for s in shapes) or len(set(shapes)) != 1:
        raise DatasetError('columns t, x, y, p have shapes '
                           f'{", ".join(str(s) for s in shapes)}: each must be one value per '
                           'event, all of one length', path=path)
    return cols


def _raw_columns(path: Path) -> tuple[NDArray[np.generic], ...]:
    """(t, x, y, p) arrays as stored, any shape."""
    if not path.is_file():
        raise DatasetError('does not exist: give a .npy or .npz event file', path=path)
    try:
        if path.suffix == '.npz':
            with np.load(path) as z:
                missing = [k for k in 'txyp' if k not in z.files]
                if missing:
                    raise DatasetError(f'has arrays {", ".join(z.files)}; needs t, x, y, p',
                                       path=path)
                return tuple(np.asarray(z[k]) for k in 'txyp')
        arr = np.load(path, mmap_mode='r', allow_pickle=False)
    except DatasetError:
        raise
    except Exception as err:  # a corrupt header fails inside numpy's parser in many ways
        raise DatasetError(f'cannot read NumPy file (truncated or not NumPy?): '
                           f'{type(err).__name__}: {err}', path=path) from err
    if arr.dtype.names is not None:
        missing = [k for k in 'txyp' if k not in arr.dtype.names]
        if missing:
            raise DatasetError(f'structured array with fields {", ".join(arr.dtype.names)}; '
                               'needs t, x, y, p', path=path)
        return tuple(arr[k] for k in 'txyp')
    if arr.ndim == 2 and arr.shape[1] == 4:
        return tuple(arr[:, i] for i in range(4))
    raise DatasetError(f'array of shape {arr.shape} and dtype {arr.dtype}: expected a '
                       'structured array with t, x, y, p or an (n, 4) array', path=path)


_MAX_NS = 9_000_000_000_000_000_000  # below int64 max: times beyond are corrupt


def _numeric(arr: NDArray[np.generic], name: str, path: Path) -> NDArray[np.generic]:
    """``arr`` if it holds integers, booleans or floats (else a DatasetError)."""
    if arr.dtype.kind not in 'biuf':
        raise DatasetError(f'column {name} has dtype {arr.dtype}: expected numbers', path=path)
    return arr


def _coordinates(arr: NDArray[np.generic], name: str, path: Path) -> NDArray[np.int64]:
    """A coordinate column as int64; NaN, infinite or huge float values are refused."""
    arr = _numeric(arr, name, path)
    if arr.dtype.kind == 'f':
        with np.errstate(invalid='ignore'):
            bad = np.flatnonzero(~(np.abs(arr) <= 1e9))
        if bad.size:
            raise DatasetError(f'event {int(bad[0])}: {name} = {arr[int(bad[0])]} is not a '
                               'pixel coordinate: a corrupt file', path=path)
    if arr.dtype.kind == 'u' and arr.dtype.itemsize == 8:
        bad = np.flatnonzero(arr > np.uint64(1 << 62))
        if bad.size:
            raise DatasetError(f'event {int(bad[0])}: {name} = {arr[int(bad[0])]} is not a '
                               'pixel coordinate: a corrupt file', path=path)
    return arr.astype(np.int64)


def npy_event_count(path: Path | str) -> int:
    """Number of events in a NumPy event file."""
    return int(_columns(Path(path))[0].shape[0])


def iter_npy_events(path: Path | str, *, time_unit: TimeUnit = 'us',
                    sensor_size: tuple[int, int] | None = None,
                    chunk_events: int = 1_000_000) -> Iterator[EventArray]:
    """Stream a NumPy event file as batches of events (int64 ns).

    Args:
        path: The ``.npy`` / ``.npz`` file.
        time_unit: Unit of ``t`` in the file.
        sensor_size: (width, height) to check coordinates against (optional).
        chunk_events: Batch size.

    Raises:
        DatasetError: unsorted times, negative or out-of-sensor coordinates, bad file.
    """
    path = Path(path)
    if time_unit not in _NS_PER:
        raise DatasetError(f'time unit {time_unit!r} is not one of {", ".join(_NS_PER)}')
    t_col, x_col, y_col, p_col = _columns(path)
    factor = _NS_PER[time_unit]
    last = -(1 << 62)
    for start in range(0, t_col.shape[0], chunk_events):
        sl = slice(start, start + chunk_events)
        t_raw = _numeric(np.asarray(t_col[sl]), 't', path)
        limit = _MAX_NS // factor
        with np.errstate(invalid='ignore'):
            far = np.flatnonzero(~(np.abs(t_raw.astype(np.float64)) <= limit))
        if far.size:
            raise DatasetError(f'event {start + int(far[0])}: time {t_raw[int(far[0])]} '
                               f'{time_unit} is not finite or beyond int64 nanoseconds: a '
                               'corrupt file or the wrong --time-unit', path=path)
        if np.issubdtype(t_raw.dtype, np.floating):
            t = np.rint(t_raw.astype(np.float64) * factor).astype(np.int64)
        else:
            t = t_raw.astype(np.int64) * factor
        x = _coordinates(np.asarray(x_col[sl]), 'x', path)
        y = _coordinates(np.asarray(y_col[sl]), 'y', path)
        p = (np.asarray(_numeric(np.asarray(p_col[sl]), 'p', path)) > 0).astype(np.uint8)
        if t.size == 0:
            continue
        bad = np.flatnonzero(np.diff(t, prepend=last) < 0)
        if bad.size:
            raise DatasetError(f'event {start + int(bad[0])}: time goes backwards; events must '
                               'be sorted by time', path=path)
        low = (x < 0) | (y < 0)
        if sensor_size is not None:
            low |= (x >= sensor_size[0]) | (y >= sensor_size[1])
        bad = np.flatnonzero(low | (x > 65535) | (y > 65535))
        if bad.size:
            i = int(bad[0])
            size = f'{sensor_size[0]}x{sensor_size[1]}' if sensor_size else 'uint16'
            raise DatasetError(f'event {start + i} at x={x[i]}, y={y[i]} is outside the {size} '
                               'sensor: give the right sensor size', path=path)
        last = int(t[-1])
        yield EventArray.from_arrays(t, x, y, p)


def read_trajectory(path: Path | str) -> Trajectory:
    """A TUM-like trajectory text file: ``t px py pz qx qy qz qw`` per line (seconds).

    Raises:
        DatasetError: naming the line for a wrong column count, a bad number or unsorted times.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError('does not exist: give a trajectory text file', path=path)
    lines = path.read_text().replace(',', ' ').split('\n')
    for i, line in enumerate(lines):      # one CSV header line ("t,px,...") before the data
        parts = line.split()
        if not parts or parts[0].startswith('#'):
            continue
        if not parts[0][:1].isdigit():
            lines[i] = ''                 # keeps the line numbers of the errors
        break
    t, v = parse_table('\n'.join(lines), 't px py pz qx qy qz qw', path, to_ns=_seconds_to_ns)
    return Trajectory(t=t, pos=np.ascontiguousarray(v[:, :3]),
                      quat=np.ascontiguousarray(v[:, 3:]))


def _seconds_to_ns(tok: str) -> int:
    """Exact ns from decimal seconds text; other notations (``1e9``) via float."""
    try:
        return seconds_to_ns(tok)
    except ValueError:
        return round(float(tok) * 1e9)
