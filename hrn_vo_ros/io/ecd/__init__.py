"""The Event Camera Dataset text layout (the dataset's own publication, IJRR 2017): read fast,
write atomically.

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

Modules: :mod:`~hrn_vo_ros.io.ecd.source` (folder or zip members, ``meta.json``, sizes and
counts), :mod:`~hrn_vo_ros.io.ecd.times` (exact decimal seconds <-> ns),
:mod:`~hrn_vo_ros.io.ecd.eventparse` (``events.txt``), :mod:`~hrn_vo_ros.io.ecd.tables` (IMU,
ground truth, calibration, whole sequences), :mod:`~hrn_vo_ros.io.ecd.writer`.

Public API (importable from this package):

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
  :func:`format_events` (``events.txt`` lines of a batch, vectorised), :func:`parse_table` and
  :func:`seconds_to_ns` (shared with the other text readers), :class:`SequenceSource`.

Measured (bench/bench_convert.py, 7 M lines, 2 shared cores): parsing 5-8 M lines/s, writing
~1.3-2 M lines/s; a 60 s sequence (23 M lines, 500 MB) streams with 85 MB peak RSS.

Times are parsed from the decimal text as integers (seconds and fraction digits separately),
never through float seconds, so nanosecond stamps are exact. Every bad input raises
:class:`~hrn_vo_ros.errors.DatasetError` naming the file and the 1-based line: a missing file, a
malformed line or wrong column count, unsorted timestamps, coordinates outside the sensor, a
polarity other than 0/1, a truncated file.
"""

from __future__ import annotations

from hrn_vo_ros.io.ecd.eventparse import iter_events, read_events
from hrn_vo_ros.io.ecd.source import (
    CALIB_FILE,
    DEFAULT_SENSOR_SIZE,
    estimate_event_count,
    event_count,
    EVENTS_FILE,
    events_size,
    GROUNDTRUTH_FILE,
    IMU_FILE,
    META_FILE,
    META_FORMAT,
    read_sensor_size,
    SequenceSource,
)
from hrn_vo_ros.io.ecd.tables import (
    parse_table,
    read_calib,
    read_groundtruth,
    read_imu,
    read_sequence,
)
from hrn_vo_ros.io.ecd.times import seconds_to_ns
from hrn_vo_ros.io.ecd.writer import format_events, write_sequence

__all__ = [
    'CALIB_FILE',
    'DEFAULT_SENSOR_SIZE',
    'EVENTS_FILE',
    'GROUNDTRUTH_FILE',
    'IMU_FILE',
    'META_FILE',
    'META_FORMAT',
    'SequenceSource',
    'estimate_event_count',
    'event_count',
    'events_size',
    'format_events',
    'iter_events',
    'parse_table',
    'read_calib',
    'read_events',
    'read_groundtruth',
    'read_imu',
    'read_sensor_size',
    'read_sequence',
    'seconds_to_ns',
    'write_sequence',
]
