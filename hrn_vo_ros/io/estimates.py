"""Estimate CSV files: one row per event frame, header ``t,h,v,r`` (plus ``z`` with scale).

Columns: ``t`` packet midpoint in seconds (sensor clock, 9 decimals, exact ns), ``h``/``v`` camera
position in the map in downsampled pixels, ``r`` roll in radians (unwrapped), ``z`` log scale.
Extra columns after these (e.g. confidences) are allowed and ignored by the reader.

Public API:

* :func:`write_estimates(path, est) <write_estimates>` — an
  :class:`~hrn_vo_ros.core.evaluation.protocol.EstimateSeries` to CSV;
* :func:`read_estimates(path) <read_estimates>` -> ``EstimateSeries``; a missing file, a header
  without t, h, v, r, a malformed row or unsorted times raise
  :class:`~hrn_vo_ros.errors.DatasetError` naming the file and line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hrn_vo_ros.core.evaluation.series import EstimateSeries
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.ecd import seconds_to_ns

REQUIRED = ('t', 'h', 'v', 'r')


def write_estimates(path: Path | str, est: EstimateSeries) -> Path:
    """Write ``est`` as CSV (overwrites ``path``); returns the path."""
    path = Path(path)
    cols = ['t', 'h', 'v', 'r'] + (['z'] if est.z is not None else [])
    lines = [','.join(cols)]
    z = est.z
    for i in range(len(est)):
        t = int(est.t[i])
        row = [f'{t // 1_000_000_000}.{t % 1_000_000_000:09d}', repr(float(est.h[i])),
               repr(float(est.v[i])), repr(float(est.r[i]))]
        if z is not None:
            row.append(repr(float(z[i])))
        lines.append(','.join(row))
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
    path = Path(path)
    if not path.is_file():
        raise DatasetError('estimate file not found (run `hrn-vo run ... --out FILE` first)',
                           path=path)
    text = path.read_text().splitlines()
    if not text:
        raise DatasetError('empty estimate file: expected a header t,h,v,r[,z]', path=path)
    header = [c.strip() for c in text[0].split(',')]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise DatasetError(f'header {text[0]!r} lacks column(s) {", ".join(missing)}; expected '
                           't,h,v,r[,z]', path=path, line=1)
    idx = {c: header.index(c) for c in header}
    has_z = 'z' in idx
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
        if len(t) > 1 and t[-1] <= t[-2]:
            raise DatasetError('times must increase from row to row', path=path, line=k)
    return EstimateSeries(np.asarray(t, dtype=np.int64), np.asarray(vals['h']),
                          np.asarray(vals['v']), np.asarray(vals['r']),
                          np.asarray(vals['z']) if has_z else None)
