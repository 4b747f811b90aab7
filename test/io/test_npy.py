"""NumPy event files (structured, columns, npz; time units) and TUM-like trajectories."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io import npy


def read_all(path: Path, **kwargs: object) -> EventArray:
    return EventArray.concatenate(list(npy.iter_npy_events(path, **kwargs)))  # type: ignore[arg-type]


def test_layouts_and_time_units(tmp_path: Path) -> None:
    t_us = np.array([1, 2, 2, 5_000_000], np.int64)
    x, y, p = np.array([0, 5, 1279, 3]), np.array([0, 719, 1, 2]), np.array([-1, 1, 0, 1])
    rec = np.zeros(4, np.dtype([('x', '<u2'), ('y', '<u2'), ('p', '<i2'), ('t', '<i8')]))
    rec['x'], rec['y'], rec['p'], rec['t'] = x, y, p, t_us
    np.save(tmp_path / 'cd.npy', rec)
    np.save(tmp_path / 'cols.npy', np.stack([t_us * 1e-6, x, y, p], axis=1))
    np.savez(tmp_path / 'arr.npz', t=t_us * 1000, x=x, y=y, p=p > 0)
    for ev in (read_all(tmp_path / 'cd.npy', chunk_events=3),
               read_all(tmp_path / 'cols.npy', time_unit='s'),
               read_all(tmp_path / 'arr.npz', time_unit='ns')):
        assert ev.t.tolist() == [1000, 2000, 2000, 5_000_000_000]
        assert ev.x.tolist() == [0, 5, 1279, 3] and ev.p.tolist() == [0, 1, 0, 1]
    assert npy.npy_event_count(tmp_path / 'cd.npy') == 4


def test_bad_event_files(tmp_path: Path) -> None:
    np.save(tmp_path / 'unsorted.npy', np.array([[5, 0, 0, 1], [4, 0, 0, 1]]))
    with pytest.raises(DatasetError, match='event 1: time goes backwards'):
        read_all(tmp_path / 'unsorted.npy')
    np.save(tmp_path / 'big.npy', np.array([[1, 2000, 0, 1]]))
    with pytest.raises(DatasetError, match='outside the 1280x720 sensor'):
        read_all(tmp_path / 'big.npy', sensor_size=(1280, 720))
    np.save(tmp_path / 'flat.npy', np.arange(10))
    with pytest.raises(DatasetError, match='expected a structured array'):
        read_all(tmp_path / 'flat.npy')
    (tmp_path / 'cut.npy').write_bytes((tmp_path / 'big.npy').read_bytes()[:100])
    with pytest.raises(DatasetError, match='cannot read NumPy'):
        read_all(tmp_path / 'cut.npy')
    # a sub-array field ('1u2' is x of shape (1,) per event) and columns of unequal length
    sub = np.zeros(3, np.dtype([('x', '1u2'), ('y', '<u2'), ('p', '<i2'), ('t', '<i8')]))
    np.save(tmp_path / 'sub.npy', sub)
    np.savez(tmp_path / 'ragged.npz', t=np.arange(3), x=np.zeros(2), y=np.zeros(3),
             p=np.zeros(3))
    for name in ('sub.npy', 'ragged.npz'):
        with pytest.raises(DatasetError, match='each must be one value per event'):
            read_all(tmp_path / name)
        with pytest.raises(DatasetError, match='each must be one value per event'):
            npy.npy_event_count(tmp_path / name)


def test_trajectory_file(tmp_path: Path) -> None:
    (tmp_path / 'traj.csv').write_text('t,px,py,pz,qx,qy,qz,qw\n'
                                       '0.5,1,2,3,0,0,0,1\n# a comment\n'
                                       '1.000000001,1,2,3,0,0,0.6,0.8\n')
    traj = npy.read_trajectory(tmp_path / 'traj.csv')
    assert traj.t.tolist() == [500_000_000, 1_000_000_001]
    assert traj.quat[1].tolist() == [0.0, 0.0, 0.6, 0.8]
    (tmp_path / 'bad.txt').write_text('0.5 1 2 3 0 0 0 1\n0.4 1 2 3 0 0 0 1\n')
    with pytest.raises(DatasetError, match='bad.txt:2: time 0.4 s is before the previous line'):
        npy.read_trajectory(tmp_path / 'bad.txt')
    (tmp_path / 'short.txt').write_text('0.5 1 2 3 0 0 0\n')
    with pytest.raises(DatasetError, match='expected 8 columns'):
        npy.read_trajectory(tmp_path / 'short.txt')
