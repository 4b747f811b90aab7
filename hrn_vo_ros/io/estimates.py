"""Estimate CSV files: one row per event frame, header ``t,h,v,r`` (plus ``z`` with scale).

Columns: ``t`` packet midpoint in seconds (sensor clock, 9 decimals, exact ns), ``h``/``v`` camera
position in the map in downsampled pixels, ``r`` roll in radians (unwrapped), ``z`` log scale.
``hrn-vo run`` appends ``quality`` (tracking quality in [0, 1]) and ``state`` (``tracking``,
``degraded`` or ``lost``); every frame keeps its row with finite h, v, r whatever its state.
Other extra columns are allowed and ignored by the reader; files without quality and state
(older ones) read as before.

Public API:

* :func:`write_estimates(path, est, *, quality=None, state=None) <write_estimates>` — an
  :class:`~hrn_vo_ros.core.evaluation.protocol.EstimateSeries` (and the per-frame quality and
  state) to CSV;
* :func:`read_estimates(path) <read_estimates>` -> ``EstimateSeries``;
  :func:`read_estimate_file(path) <read_estimate_file>` -> :class:`EstimateFile` (the series
  plus the quality and state columns when present); a missing file, a header without t, h, v,
  r, a file that is not UTF-8 text, a malformed row, an unknown state or unsorted times raise
  :class:`~hrn_vo_ros.errors.DatasetError` naming the file and line;
* :func:`write_tum(path, est, cfg) <write_tum>` — the estimate as a TUM trajectory (below).

TUM trajectories (``timestamp tx ty tz qx qy qz qw``, space-separated, seconds and metres,
``#`` header line): the pose of the camera's optical frame (x right, y down, z forward) at each
frame time, relative to the camera at the first frame, as
:func:`~hrn_vo_ros.core.odometry.odometry.camera_pose` reads it out: the rotation kind gives
the orientation from ``h``, ``v``, ``r`` (``f`` the focal length in frame pixels) through the
config's ``odometry.projection``: pinhole ``Ry(pan) Rx(tilt) Rz(roll)`` with
``pan = atan(h / f)``, ``tilt = -atan(v / f)``; equidistant (frames rectified equidistant) the
swing of angle ``|(h, v)| / f`` about ``(-v, h, 0)``, then ``Rz(roll)``; zero position; the
translation kind gives the position ``(h d / f, v d / f, d (1 - exp(-z)))`` at the scene depth
``d`` with the roll as the orientation. The ground truth of the Event Camera Dataset
(``groundtruth.txt``: ``t px py pz qx qy qz qw``, camera in the world) is already in this form;
as the estimate starts at the identity, compare them after aligning the first pose (e.g. evo's
origin alignment, ``evo_ape tum groundtruth.txt est.tum --align_origin``). evo pairs each pose
with the nearest stamp of the other file (within ``--t_max_diff``, 10 ms by default): against a
100-200 Hz motion-capture ground truth at hundreds of degrees per second that pairing alone adds
tenths of a degree, so pass a ``--t_max_diff`` of about half a frame interval (the simulator's
ground truth is at 1 kHz).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.evaluation.series import EstimateSeries
from hrn_vo_ros.core.odometry.odometry import camera_pose, OdometryConfig, quat_from_matrix
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.ecd import seconds_to_ns

REQUIRED = ('t', 'h', 'v', 'r')
STATES = ('tracking', 'degraded', 'lost')
"""The tracking states a ``state`` column may hold."""


@dataclass(frozen=True, slots=True, eq=False)
class EstimateFile:
    """An estimate CSV: the series and, when the file has them, the quality and state columns.

    Shapes:
        quality: (n,) float64 or None; state: n strings of :data:`STATES` or None.
    """

    series: EstimateSeries
    quality: NDArray[np.float64] | None = None
    state: list[str] | None = None


def _stamp(t: int) -> str:
    return f'{t // 1_000_000_000}.{t % 1_000_000_000:09d}'


def write_estimates(path: Path | str, est: EstimateSeries, *,
                    quality: Sequence[float] | NDArray[np.float64] | None = None,
                    state: Sequence[str] | None = None) -> Path:
    """Write ``est`` as CSV (overwrites ``path``); returns the path.

    Args:
        path: The CSV to write.
        est: The readouts.
        quality: Per-frame tracking quality (a ``quality`` column), or None.
        state: Per-frame tracking state (a ``state`` column, :data:`STATES`), or None.

    Raises:
        DatasetError: if ``quality`` or ``state`` do not have one entry per frame.
    """
    path = Path(path)
    n = len(est)
    for name, col in (('quality', quality), ('state', state)):
        if col is not None and len(col) != n:
            raise DatasetError(f'{len(col)} {name} values for {n} frames', path=path)
    cols = (['t', 'h', 'v', 'r'] + (['z'] if est.z is not None else [])
            + (['quality'] if quality is not None else []) + (['state'] if state is not None
                                                              else []))
    lines = [','.join(cols)]
    z = est.z
    for i in range(n):
        row = [_stamp(int(est.t[i])), repr(float(est.h[i])), repr(float(est.v[i])),
               repr(float(est.r[i]))]
        if z is not None:
            row.append(repr(float(z[i])))
        if quality is not None:
            row.append(repr(float(quality[i])))
        if state is not None:
            row.append(str(state[i]))
        lines.append(','.join(row))
    path.write_text('\n'.join(lines) + '\n')
    return path


def write_tum(path: Path | str, est: EstimateSeries, cfg: OdometryConfig) -> Path:
    """Write ``est`` as a TUM trajectory of the camera's optical frame (see the module
    docstring); ``cfg`` gives the motion model, focal length, depth and scale. Returns the
    path."""
    path = Path(path)
    lines = ['# timestamp tx ty tz qx qy qz qw (camera optical frame: x right, y down, '
             'z forward; relative to the first frame)']
    for i in range(len(est)):
        z = None if est.z is None else float(est.z[i])
        pos, R, _ = camera_pose(cfg, float(est.h[i]), float(est.v[i]), float(est.r[i]), z, {})
        q = quat_from_matrix(R)
        lines.append(' '.join([_stamp(int(est.t[i]))] + [f'{x:.9g}' for x in (*pos, *q)]))
    path.write_text('\n'.join(lines) + '\n')
    return path


def _time_ns(tok: str, path: Path, line: int) -> int:
    try:
        return seconds_to_ns(tok.strip())
    except ValueError:
        raise DatasetError(f'bad time {tok!r} (expected seconds >= 0 with up to 9 decimals)',
                           path=path, line=line) from None


def read_estimates(path: Path | str) -> EstimateSeries:
    """Read an estimate CSV written by ``hrn-vo run`` (see the module docstring).

    Raises:
        DatasetError: naming the file and line on any bad input.
    """
    return read_estimate_file(path).series


def read_estimate_file(path: Path | str) -> EstimateFile:
    """Read an estimate CSV with its quality and state columns (None where absent).

    Raises:
        DatasetError: naming the file and line on any bad input.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError('estimate file not found (run `hrn-vo run ... --out FILE` first)',
                           path=path)
    try:
        text = path.read_bytes().decode('utf-8').splitlines()
    except UnicodeDecodeError as err:
        raise DatasetError(f'not a text estimate CSV (not UTF-8 at byte {err.start}); expected '
                           'a header t,h,v,r[,z]', path=path) from None
    except OSError as err:
        raise DatasetError(f'cannot read the estimate file: {err.strerror or err}',
                           path=path) from None
    if not text:
        raise DatasetError('empty estimate file: expected a header t,h,v,r[,z]', path=path)
    header = [c.strip() for c in text[0].split(',')]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise DatasetError(f'header {text[0]!r} lacks column(s) {", ".join(missing)}; expected '
                           't,h,v,r[,z]', path=path, line=1)
    idx = {c: header.index(c) for c in header}
    has_z = 'z' in idx
    quality: list[float] | None = [] if 'quality' in idx else None
    state: list[str] | None = [] if 'state' in idx else None
    t = []
    vals: dict[str, list[float]] = {c: [] for c in ('h', 'v', 'r', 'z')}
    for k, line in enumerate(text[1:], start=2):
        if not line.strip():
            continue
        parts = line.split(',')
        if len(parts) < len(header):
            raise DatasetError(f'{len(parts)} columns, expected {len(header)} ({text[0]})',
                               path=path, line=k)
        t.append(_time_ns(parts[idx['t']], path, k))
        for c in ('h', 'v', 'r', 'z'):
            if c == 'z' and not has_z:
                continue
            try:
                vals[c].append(float(parts[idx[c]]))
            except ValueError:
                raise DatasetError(f'column {c}: {parts[idx[c]]!r} is not a number', path=path,
                                   line=k) from None
        if quality is not None:
            try:
                quality.append(float(parts[idx['quality']]))
            except ValueError:
                raise DatasetError(f'column quality: {parts[idx["quality"]]!r} is not a number',
                                   path=path, line=k) from None
        if state is not None:
            st = parts[idx['state']].strip()
            if st not in STATES:
                raise DatasetError(f'column state: {st!r} is not one of {", ".join(STATES)}',
                                   path=path, line=k)
            state.append(st)
        if len(t) > 1 and t[-1] <= t[-2]:
            raise DatasetError('times must increase from row to row', path=path, line=k)
    series = EstimateSeries(np.asarray(t, dtype=np.int64), np.asarray(vals['h']),
                            np.asarray(vals['v']), np.asarray(vals['r']),
                            np.asarray(vals['z']) if has_z else None)
    return EstimateFile(series, None if quality is None else np.asarray(quality), state)
