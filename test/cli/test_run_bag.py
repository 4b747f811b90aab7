"""``hrn-vo run BAG``: the driver bags (evt3, libcaer_cmp), a converted synthetic bag, TUM."""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from hrn_vo_ros.io.estimates import read_estimate_file

ROOT = Path(__file__).resolve().parents[2]
BAGS = ROOT.parent / 'shared' / 'data' / 'driver_bags'
SETS = ['--config', str(ROOT / 'config' / 'shapes_rotation.yaml'),
        '--set', 'packetizer.rectify=none', '--set', 'sphere.enabled=false',
        '--set', 'codebook.canvas_width=0', '--set', 'codebook.canvas_height=0']


def hrn_vo(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'hrn_vo_ros.cli.main', *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=600,
                          env={'PYTHONPATH': str(ROOT), 'PATH': '/usr/bin:/bin',
                               'HOME': str(Path.home())})


#: live.yaml as it is: no calibration needed, the canvas follows each sensor's frame size
#: (640x480 and 346x260 here: 96x72 frames, downsample 0 = auto: 6.667 and 3.611)
LIVE = ['--config', str(ROOT / 'config' / 'live.yaml')]
AUTO = {'test_events_1': '6.667', 'test_events_2': '3.611'}    # 640 / 96, 260 / 72
LIVE_TRANSLATION = ['--config', str(ROOT / 'config' / 'live_translation.yaml')]


@pytest.mark.parametrize(('sets', 'packet'),
                         [(SETS, 2000), (LIVE, 2000), (LIVE_TRANSLATION, 1000)],
                         ids=['shapes_rotation', 'live', 'live_translation'])
@pytest.mark.parametrize(('name', 'events'), [('test_events_1', 343474),
                                              ('test_events_2', 571266)])
def test_driver_bag(tmp_path: Path, name: str, events: int, sets: list[str],
                    packet: int) -> None:
    bag = BAGS / name
    if not bag.is_dir():
        pytest.skip(f'driver bag {bag} not present')
    out = tmp_path / 'est.csv'
    res = hrn_vo('run', str(bag), *sets, '--out', str(out), '--quiet')
    assert res.returncode == 0, res.stderr
    assert f'{events} change events' in res.stdout
    ef = read_estimate_file(out)
    assert len(ef.series) == events // packet      # the config's events per frame
    if sets is not SETS:               # the live configs' auto downsample: 96x72 from both
        assert f'{len(ef.series)} frames of 96x72 (downsample {AUTO[name]})' in res.stdout
    assert ef.state is not None and ef.quality is not None
    line = next(x for x in res.stdout.splitlines() if 'header stamps' in x)
    span = line.split('header stamps ')[1].split(' s,')[0].split('..')
    lo, hi = (round(float(v) * 1e9) for v in span)
    t = ef.series.t
    assert lo - 1000 <= t[0] and t[-1] <= hi + 1000     # printed with 6 decimals
    assert np.all(np.diff(t) > 0) and np.all(np.isfinite(ef.series.h))


@pytest.fixture(scope='module')
def rot_seq(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp('rot') / 'seq'
    res = hrn_vo('simulate', str(d), '--kind', 'rotation', '--seconds', '6', '--seed', '1')
    assert res.returncode == 0, res.stderr
    return d


def test_synthetic_bag(tmp_path: Path, rot_seq: Path) -> None:
    bag = tmp_path / 'bag'
    res = hrn_vo('convert', str(rot_seq), str(bag))
    assert res.returncode == 0, res.stderr
    out = tmp_path / 'est.csv'
    res = hrn_vo('run', str(bag), *SETS, '--out', str(out), '--quiet')
    assert res.returncode == 0, res.stderr
    ef = read_estimate_file(out)
    assert len(ef.series) > 100 and ef.state is not None


def test_dataset_needs_sensor_size(tmp_path: Path, rot_seq: Path) -> None:
    seq = tmp_path / 'nometa'
    seq.mkdir()
    for f in rot_seq.iterdir():
        if f.name != 'meta.json':
            (seq / f.name).write_bytes(f.read_bytes())
    res = hrn_vo('run', str(seq), '--out', str(tmp_path / 'e.csv'), '--quiet')
    assert res.returncode != 0 and '--sensor-size' in res.stderr


def test_tum_rotation(tmp_path: Path, rot_seq: Path) -> None:
    est, tum = tmp_path / 'est.csv', tmp_path / 'est.tum'
    res = hrn_vo('run', str(rot_seq), '--config', str(ROOT / 'config' / 'shapes_rotation.yaml'),
                 '--out', str(est), '--tum', str(tum), '--quiet')
    assert res.returncode == 0, res.stderr
    ev = hrn_vo('evaluate', str(rot_seq), str(est), '--kind', 'rotation', '--json')
    assert ev.returncode == 0, ev.stderr
    import json
    doc = json.loads(ev.stdout.strip().splitlines()[-1])
    median = doc['metrics']['median_angle_deg']
    e = np.loadtxt(tum)
    g = np.loadtxt(rot_seq / 'groundtruth.txt')
    assert e.shape[1] == 8
    # ground truth interpolated (slerp) at the estimate times shifted by the protocol's lag, as
    # evaluate does; first poses aligned (evo's origin alignment); geodesic angle per frame
    from scipy.spatial.transform import Rotation, Slerp
    t = e[:, 0] - doc['lag_s']
    keep = (t >= g[0, 0]) & (t <= g[-1, 0])
    rg = Slerp(g[:, 0], Rotation.from_quat(g[:, 4:]))(t[keep])
    re = Rotation.from_quat(e[keep, 4:])
    err = (rg[0].inv() * rg).inv() * (re[0].inv() * re)
    geo = float(np.median(np.degrees(err.magnitude())))
    # within 2x of the protocol's median (which also fits the scale): measured 0.32 vs 0.26 deg
    # on this sequence; the pinhole (atan) reading of equidistant frames gave 0.65
    assert geo <= 2 * median, (geo, median)


def test_bag_with_a_camera_info_gives_the_focal_length(tmp_path: Path, rot_seq: Path) -> None:
    """No calib.txt beside a bag: its CameraInfo gives fx / D, for the gyro and the TUM poses
    (before, the gyro refused to start without --set focal_px)."""
    bag = tmp_path / 'bag'
    assert hrn_vo('convert', str(rot_seq), str(bag)).returncode == 0
    fx = float((rot_seq / 'calib.txt').read_text().split()[0])
    est, tum = tmp_path / 'est.csv', tmp_path / 'est.tum'
    res = hrn_vo('run', str(bag), *LIVE, '--imu-topic', '/imu', '--out', str(est),
                 '--tum', str(tum), '--quiet')
    assert res.returncode == 0, res.stderr
    assert (f"note: focal length {fx / 2.5:.4g} frame px from the bag's CameraInfo (fx {fx:g} "
            'on 240x180, frames 96x72)') in res.stdout
    ef = read_estimate_file(est)
    assert len(ef.series) > 100
    e = np.loadtxt(tum)
    from scipy.spatial.transform import Rotation
    R = Rotation.from_quat(e[:, 4:]).as_matrix()
    pan = np.arctan2(R[:, 0, 2], R[:, 2, 2])         # R = Ry(pan) Rx(tilt) Rz(roll)
    h = ef.series.h
    moved = np.abs(h) > 1.0
    assert moved.sum() > 50
    np.testing.assert_allclose(pan[moved], np.arctan(h[moved] / (fx / 2.5)), rtol=1e-6)
    assert fx / 2.5 != pytest.approx(79.6, rel=1e-5)      # not live.yaml's focal_length_px
    if (BAGS / 'test_events_2').is_dir():     # no CameraInfo (a driver bag): still refused
        res = hrn_vo('run', str(BAGS / 'test_events_2'), *LIVE, '--set', 'imu.enabled=true',
                     '--out', str(tmp_path / 'e2.csv'), '--quiet')
        assert res.returncode != 0 and 'nor a calibrated CameraInfo' in res.stderr


def test_bag_with_a_camera_info_rectifies_as_the_dataset_does(tmp_path: Path,
                                                              rot_seq: Path) -> None:
    """shapes_rotation.yaml (equidistant rectification, sphere correction) on a converted bag:
    the CameraInfo gives the intrinsics and the focal length that calib.txt gives the dataset
    run, so the estimates are the same values (before: refused, no calib.txt)."""
    bag = tmp_path / 'bag'
    assert hrn_vo('convert', str(rot_seq), str(bag)).returncode == 0
    cfg = ['--config', str(ROOT / 'config' / 'shapes_rotation.yaml'), '--quiet']
    res = hrn_vo('run', str(bag), *cfg, '--out', str(tmp_path / 'bag.csv'))
    assert res.returncode == 0, res.stderr
    assert "rectification (equidistant) with the bag's CameraInfo calibration" in res.stdout
    assert hrn_vo('run', str(rot_seq), *cfg, '--out', str(tmp_path / 'ds.csv')).returncode == 0
    a = read_estimate_file(tmp_path / 'bag.csv').series
    b = read_estimate_file(tmp_path / 'ds.csv').series
    assert len(a.h) == len(b.h) > 100
    for x, y in ((a.h, b.h), (a.v, b.v), (a.r, b.r)):
        np.testing.assert_array_equal(x, y)
    # rectified frames differ from plain ones: the calibration was used, not skipped
    plain = tmp_path / 'plain.csv'
    assert hrn_vo('run', str(bag), *cfg, '--set', 'packetizer.rectify=none', '--set',
                  'sphere.enabled=false', '--out', str(plain)).returncode == 0
    assert not np.array_equal(read_estimate_file(plain).series.h[:len(a.h)], a.h)
