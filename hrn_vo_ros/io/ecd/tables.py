"""The small text tables of a sequence: ``imu.txt``, ``groundtruth.txt``, ``calib.txt``, and
the whole sequence in memory."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
import warnings

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.sequence import CameraCalibration, ImuData, Sequence, Trajectory
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.ecd.eventparse import read_events
from hrn_vo_ros.io.ecd.source import (
    CALIB_FILE,
    GROUNDTRUTH_FILE,
    IMU_FILE,
    meta_count,
    META_FILE,
    read_meta,
    SequenceSource,
    source_sensor_size,
)
from hrn_vo_ros.io.ecd.times import seconds_to_ns


def _read_table(src: SequenceSource, name: str, columns: str,
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


def _check_count(src: SequenceSource, name: str, key: str, n: int) -> None:
    expected = meta_count(read_meta(src), key)
    if expected is not None and expected != n:
        raise DatasetError(f'has {n} lines but {META_FILE} records {expected}: the file is '
                           'truncated or was edited', path=src.where(name))


MAX_ABS_GYRO = 1e3
"""Largest plausible angular rate (rad/s; MEMS gyros saturate below 100 rad/s)."""
MAX_ABS_ACC = 1e4
"""Largest plausible acceleration (m/s^2; about 1000 g)."""
MAX_ABS_POSITION = 1e7
"""Largest plausible ground-truth coordinate (m)."""
QUAT_NORM_TOL = 0.1
"""Ground-truth quaternions must have a norm within 1 +- this (unit quaternions)."""


def _line_of_row(text: str, row: int) -> int:
    """1-based line number of data row ``row`` of a table (blank and ``#`` lines skipped)."""
    k = -1
    for i, line in enumerate(text.split('\n')):
        parts = line.split()
        if parts and not parts[0].startswith('#'):
            k += 1
            if k == row:
                return i + 1
    return row + 1


def _check_range(src: SequenceSource, name: str, values: NDArray[np.float64], limit: float,
                 what: str) -> None:
    """Refuse table values beyond ``limit`` in magnitude, naming the line.

    Raises:
        DatasetError: for the first row holding such a value.
    """
    bad = np.flatnonzero(np.any(np.abs(values) > limit, axis=1))
    if bad.size:
        row = int(bad[0])
        line = _line_of_row(src.read_text(name), row)
        raise DatasetError(f'{what} {values[row].tolist()} exceeds {limit:g} in magnitude: a '
                           'corrupt line, or the wrong unit; fix or remove the line',
                           path=src.where(name), line=line)


def read_imu(path: Path | str) -> ImuData:
    """``imu.txt`` (``t ax ay az gx gy gz``) of a sequence folder or zip.

    Raises:
        DatasetError: for a malformed line (see :func:`parse_table`), or an implausible value
            (gyro beyond :data:`MAX_ABS_GYRO` rad/s, acceleration beyond :data:`MAX_ABS_ACC`).
    """
    with SequenceSource(path) as src:
        t, v = _read_table(src, IMU_FILE, 't ax ay az gx gy gz')
        _check_count(src, IMU_FILE, 'imu', t.size)
        _check_range(src, IMU_FILE, v[:, :3], MAX_ABS_ACC, 'acceleration (m/s^2)')
        _check_range(src, IMU_FILE, v[:, 3:], MAX_ABS_GYRO, 'angular rate (rad/s)')
    return ImuData(t=t, acc=np.ascontiguousarray(v[:, :3]), gyro=np.ascontiguousarray(v[:, 3:]))


def read_groundtruth(path: Path | str) -> Trajectory:
    """``groundtruth.txt`` (``t px py pz qx qy qz qw``) of a sequence folder or zip.

    Raises:
        DatasetError: for a malformed line (see :func:`parse_table`), a position beyond
            :data:`MAX_ABS_POSITION` m or a quaternion that is not of unit norm (a zero one).
    """
    with SequenceSource(path) as src:
        t, v = _read_table(src, GROUNDTRUTH_FILE, 't px py pz qx qy qz qw')
        _check_count(src, GROUNDTRUTH_FILE, 'groundtruth', t.size)
        _check_range(src, GROUNDTRUTH_FILE, v[:, :3], MAX_ABS_POSITION, 'position (m)')
        norm = np.linalg.norm(v[:, 3:], axis=1)
        bad = np.flatnonzero(np.abs(norm - 1.0) > QUAT_NORM_TOL)
        if bad.size:
            row = int(bad[0])
            line = _line_of_row(src.read_text(GROUNDTRUTH_FILE), row)
            raise DatasetError(f'quaternion {v[row, 3:].tolist()} has norm {norm[row]:.3g}, '
                               'expected a unit quaternion (qx qy qz qw): a corrupt line; fix '
                               'or remove it', path=src.where(GROUNDTRUTH_FILE), line=line)
    return Trajectory(t=t, pos=np.ascontiguousarray(v[:, :3]),
                      quat=np.ascontiguousarray(v[:, 3:]))


def read_calib(path: Path | str) -> CameraCalibration:
    """``calib.txt`` (``fx fy cx cy k1 k2 p1 p2 k3``) plus the sensor size."""
    with SequenceSource(path) as src:
        width, height = source_sensor_size(src)
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
    with SequenceSource(path) as src:
        has_imu, has_gt = src.exists(IMU_FILE), src.exists(GROUNDTRUTH_FILE)
    return Sequence(events=read_events(path), calib=read_calib(path),
                    imu=read_imu(path) if has_imu else None,
                    groundtruth=read_groundtruth(path) if has_gt else None)
