"""Estimate CSV round trip and errors; ``hrn-vo evaluate`` end to end on a written dataset."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hrn_vo_ros.cli.main import main
from hrn_vo_ros.core.evaluation.series import EstimateSeries
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import CameraCalibration, Sequence, Trajectory
from hrn_vo_ros.core.odometry.geometry import (
    euler_ptr_to_matrix,
    matrix_to_quat,
    matrix_to_swing_twist,
)
from hrn_vo_ros.core.odometry.odometry import OdometryConfig
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.ecd import write_sequence
from hrn_vo_ros.io.estimates import read_estimates, write_estimates, write_tum


def test_round_trip_is_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.integers(1, 10_000_000, 50)).astype(np.int64)
    est = EstimateSeries(t, rng.normal(size=50), rng.normal(size=50), rng.normal(size=50),
                         rng.normal(size=50))
    back = read_estimates(write_estimates(tmp_path / 'e.csv', est))
    np.testing.assert_array_equal(back.t, est.t)
    for name in ('h', 'v', 'r', 'z'):
        np.testing.assert_array_equal(getattr(back, name), getattr(est, name))
    no_z = read_estimates(write_estimates(tmp_path / 'f.csv', EstimateSeries(t, est.h, est.v,
                                                                             est.r)))
    assert no_z.z is None


@pytest.mark.parametrize('text, message, line', [
    ('t,h,v\n0.1,1,2\n', 'lacks column', 1),
    ('t,h,v,r\n0.1,1,2\n', 'columns, expected 4', 2),
    ('t,h,v,r\n0.1,1,x,3\n', "'x' is not a number", 2),
    ('t,h,v,r\n0.2,1,2,3\n0.1,1,2,3\n', 'increase', 3),
    ('t,h,v,r\n0.2,1,2,3\n0.2,1,2,4\n', 'increase', 3),
    ('t,h,v,r\nabc,1,2,3\n', 'bad time', 2),
    ('', 'empty', None),
])
def test_bad_files_name_file_and_line(tmp_path: Path, text: str, message: str,
                                      line: int | None) -> None:
    path = tmp_path / 'bad.csv'
    path.write_text(text)
    with pytest.raises(DatasetError, match=message) as info:
        read_estimates(path)
    assert info.value.line == line
    assert str(path) in str(info.value)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match='not found'):
        read_estimates(tmp_path / 'nope.csv')


@pytest.mark.parametrize('data', [b'\xff\xfe\x00\x01binary', b't,h,v,r\n0.1,1,2,\xe9\n',
                                  bytes(range(256))])
def test_binary_file_is_a_dataset_error_naming_the_file(tmp_path: Path, data: bytes) -> None:
    f = tmp_path / 'est.bin'
    f.write_bytes(data)
    with pytest.raises(DatasetError, match=r'est\.bin.*not UTF-8'):
        read_estimates(f)


def _dataset(tmp_path: Path) -> tuple[Path, Path]:
    t = np.arange(0.0, 20.0, 1 / 200)
    pan, tilt, roll = 0.3 * np.sin(0.5 * t), 0.2 * np.sin(0.8 * t + 1), 0.6 * np.sin(0.3 * t)
    R = euler_ptr_to_matrix(pan, tilt, roll)
    gt = Trajectory((t * 1e9).astype(np.int64), np.zeros((len(t), 3)), matrix_to_quat(R))
    ev = EventArray.from_arrays(np.array([0, 1]), np.array([1, 2]), np.array([1, 2]),
                                np.array([0, 1]))
    seq = Sequence(ev, CameraCalibration(240, 180, 199.0, 199.0, 120.0, 90.0), None, gt)
    ds = write_sequence(tmp_path / 'ds', seq)
    te = np.arange(0.01, 19.99, 1 / 150)
    Re = euler_ptr_to_matrix(np.interp(te, t, pan), np.interp(te, t, tilt),
                             np.interp(te, t, roll))
    p, q, r = matrix_to_swing_twist(np.swapaxes(Re[:1], 1, 2) @ Re)   # the default convention
    est = EstimateSeries((te * 1e9).astype(np.int64), 80 * p, -80 * q, np.unwrap(r))
    return ds, write_estimates(tmp_path / 'est.csv', est)


def test_evaluate_cli_table_json_and_plot(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    ds, est = _dataset(tmp_path)
    png = tmp_path / 'plot.png'
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation', '--plot', str(png)]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert any(line.startswith('median_angle_deg') for line in out)
    result = json.loads(out[-1])
    assert result['metrics']['median_angle_deg'] < 0.1
    # the turn from one estimate to the next (1/150 s), from the trace of the relative
    # rotation of the ground truth at the estimate times (linear in the angles: the same as
    # the geodesic interpolation to far below the rounding)
    te = np.arange(0.01, 19.99, 1 / 150)
    Rg = euler_ptr_to_matrix(0.3 * np.sin(0.5 * te), 0.2 * np.sin(0.8 * te + 1),
                             0.6 * np.sin(0.3 * te))
    rel = np.einsum('nji,njk->nik', Rg[:-1], Rg[1:])
    cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1)
    want = float(np.percentile(np.degrees(np.arccos(cos)), 95))
    assert 0.09 < want < 0.11
    assert result['motion']['turn_deg_p95'] == pytest.approx(want, abs=2e-4)
    assert result['motion']['travel_m_p95'] == 0
    assert f'motion between estimates (95th percentile): turn {want:.2f} deg, travel 0.00 cm' \
        in out
    assert png.stat().st_size > 10_000
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation', '--json',
                 '--calib', 'full']) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and json.loads(lines[0])['calib'] == 'full'
    # the same swing-twist estimate read as Euler angles misses the pan * tilt / 2 twist
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation', '--json',
                 '--convention', 'euler']) == 0
    euler = json.loads(capsys.readouterr().out.strip())
    assert euler['calibration']['convention'] == 'euler'
    assert euler['metrics']['median_angle_deg'] > 0.2
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation', '--json',
                 '--roll-zero', '1.5']) == 0
    assert json.loads(capsys.readouterr().out.strip())['calibration']['roll_zero_s'] == 1.5
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation',
                 '--lag-window', 'training']) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert any(line.startswith('lag ') and line.endswith('searched before the evaluated part')
               for line in out)
    assert json.loads(out[-1])['calibration']['lag_window'] == 'training'
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation', '--lag-scan', '3']) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert any(line.startswith('lag scan (median_angle_deg)') for line in out)
    scan = json.loads(out[-1])['lag_scan']
    assert scan['offsets_ms'] == [-3, -2, -1, 0, 1, 2, 3] and len(scan['values']) == 7
    # a lag-free estimate: errors grow away from the protocol lag
    assert abs(scan['best_offset_ms']) <= 1
    assert scan['values'][3] < min(scan['values'][0], scan['values'][6])


def test_evaluate_plot_into_a_folder_and_bad_plot_paths(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    """``--plot DIR`` (an existing folder) writes DIR/trajectory.png and prints that path, never
    a DIR.png next to it; a name without suffix is written exactly as named; a missing folder
    or an unknown suffix are refused before anything is written."""
    ds, est = _dataset(tmp_path)
    folder = tmp_path / 'plots'
    folder.mkdir()
    base = ['evaluate', str(ds), str(est), '--kind', 'rotation', '--plot']
    assert main([*base, str(folder)]) == 0
    assert f'plot: {folder / "trajectory.png"}' in capsys.readouterr().out
    assert (folder / 'trajectory.png').stat().st_size > 10_000
    assert not (tmp_path / 'plots.png').exists()
    assert main([*base, str(tmp_path / 'bare')]) == 0
    assert f'plot: {tmp_path / "bare"}\n' in capsys.readouterr().out
    assert (tmp_path / 'bare').read_bytes()[:4] == b'\x89PNG'
    assert not (tmp_path / 'bare.png').exists()
    assert main([*base, str(tmp_path / 'missing' / 'p.png')]) == 2
    err = capsys.readouterr().err
    assert '--plot' in err and 'does not exist' in err and str(tmp_path / 'missing') in err
    assert not (tmp_path / 'missing').exists()
    assert main([*base, str(tmp_path / 'p.xyz')]) == 2
    assert '.xyz is no image format' in capsys.readouterr().err


def test_evaluate_states_json_is_strict_when_a_state_never_occurs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ds, est = _dataset(tmp_path)
    series = read_estimates(est)
    write_estimates(est, series, quality=np.ones(len(series)), state=['tracking'] * len(series))
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation']) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert any(line.startswith('lost') and 'no evaluated samples' in line for line in out)

    def no_constants(name: str) -> None:
        raise AssertionError(f'{name} in the JSON line')

    states = json.loads(out[-1], parse_constant=no_constants)['states']
    assert states['lost'] == {'seconds': 0.0, 'median_error': None, 'evaluated': 0}
    assert states['tracking']['median_error'] < 0.1


def test_evaluate_calibration_on_tracking_states(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """An output held still (and flagged lost) over 4-8 s of the calibration segment skews the
    protocol's fit; ``--calib-states tracking`` fits on the rest and is exact again (80 px per
    rad: scale 1/80); without a state column the option is refused."""
    ds, est = _dataset(tmp_path)
    series = read_estimates(est)
    ts = series.t * 1e-9
    held = (ts > 4.0) & (ts < 8.0)
    h, v = series.h.copy(), series.v.copy()
    h[held], v[held] = h[held][0], v[held][0]
    state = np.where(held, 'lost', 'tracking').tolist()
    write_estimates(est, EstimateSeries(series.t, h, v, series.r),
                    quality=np.where(held, 0.0, 1.0), state=state)
    base = ['evaluate', str(ds), str(est), '--kind', 'rotation', '--json']
    assert main(base) == 0
    plain = json.loads(capsys.readouterr().out.strip())
    assert abs(plain['calibration']['scale'] * 80.0 - 1.0) > 0.05
    assert main([*base, '--calib-states', 'tracking']) == 0
    fixed = json.loads(capsys.readouterr().out.strip())
    assert fixed['calibration']['scale'] == pytest.approx(1 / 80.0, rel=2e-3)
    assert fixed['metrics']['median_angle_deg'] < 0.1 < plain['metrics']['median_angle_deg']
    bare = tmp_path / 'bare.csv'
    write_estimates(bare, series)
    assert main(['evaluate', str(ds), str(bare), '--kind', 'rotation',
                 '--calib-states', 'tracking']) == 2
    assert 'no state column' in capsys.readouterr().err


def test_evaluate_cli_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ds, est = _dataset(tmp_path)
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation', '--lag-scan', '-2']) == 2
    assert '--lag-scan' in capsys.readouterr().err
    assert main(['evaluate', str(ds), str(est), '--kind', 'rotation', '--roll-zero', '-1']) == 2
    assert 'roll zeroing window' in capsys.readouterr().err
    assert main(['evaluate', str(ds), str(tmp_path / 'missing.csv'), '--kind', 'rotation']) == 3
    assert 'not found' in capsys.readouterr().err
    short = tmp_path / 'short.csv'
    short.write_text('\n'.join(est.read_text().splitlines()[:6]) + '\n')
    assert main(['evaluate', str(ds), str(short), '--kind', 'rotation']) == 3
    assert 'only 5 estimates' in capsys.readouterr().err


def test_quality_state_columns_round_trip(tmp_path: Path) -> None:
    from hrn_vo_ros.io.estimates import read_estimate_file
    est = EstimateSeries(np.array([1, 2, 3], dtype=np.int64), np.zeros(3), np.ones(3),
                         np.zeros(3))
    p = write_estimates(tmp_path / 'e.csv', est, quality=[1.0, 0.5, 0.1],
                        state=['tracking', 'degraded', 'lost'])
    assert p.read_text().splitlines()[0] == 't,h,v,r,quality,state'
    ef = read_estimate_file(p)
    assert ef.state == ['tracking', 'degraded', 'lost']
    assert ef.quality is not None and list(ef.quality) == [1.0, 0.5, 0.1]
    old = write_estimates(tmp_path / 'old.csv', est)
    assert read_estimate_file(old).state is None


def test_tum_rows_by_hand(tmp_path: Path) -> None:
    """The rotation model at the map's origin: no translation, a roll r about the optical axis
    is the quaternion (0, 0, sin r/2, cos r/2); stamps in seconds with nine decimals."""
    est = EstimateSeries(np.array([1_500_000_000, 2_000_000_007]), np.zeros(2), np.zeros(2),
                         np.array([0.0, np.pi / 2]))
    lines = write_tum(tmp_path / 'e.tum', est, OdometryConfig()).read_text().splitlines()
    assert lines[0].startswith('# timestamp tx ty tz qx qy qz qw')
    assert lines[1:] == ['1.500000000 0 0 0 0 0 0 1',
                         '2.000000007 0 0 0 0 0 0.707106781 0.707106781']
