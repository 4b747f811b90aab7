"""The event-camera simulator: rates, polarity balance, refractory period, IMU vs. GT, seeds."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hrn_vo_ros.cli.main import main
from hrn_vo_ros.core.events.arrays import EventChecksum
from hrn_vo_ros.core.events.sequence import Sequence, Trajectory
from hrn_vo_ros.core.odometry.geometry import (
    euler_ptr_to_matrix,
    matrix_to_quat,
    quat_to_matrix,
    rot_z,
    rotation_angle,
    so3_exp,
)
from hrn_vo_ros.core.sim.simulator import (
    describe_motion,
    optical_axis_estimate,
    PLANE_Z,
    simulate,
    SimulatorConfig,
)
from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io.ecd import read_calib, read_groundtruth, read_imu, read_sensor_size

QUIET = SimulatorConfig(noise_rate_hz=0.0, hot_pixels=0, gyro_noise=0.0, gyro_bias=0.0,
                        acc_noise=0.0, acc_bias=0.0)


@pytest.fixture(scope='module')
def rotation() -> Sequence:
    return simulate('rotation', 1.0, seed=11)


@pytest.fixture(scope='module')
def quiet_rotation() -> Sequence:
    return simulate('rotation', 0.5, seed=12, config=QUIET)


def _checksum(seq: Sequence) -> str:
    c = EventChecksum()
    c.update(seq.events)
    return c.hexdigest()


def test_rotation_rate_polarity_and_layout(rotation: Sequence) -> None:
    ev = rotation.events
    info = describe_motion(rotation)
    # the first second is the slow start of the speed ramp: 0.05–1 M events/s
    assert 5e4 < info['events_per_s'] < 1e6
    assert 0.4 < info['on_fraction'] < 0.6
    assert np.all(np.diff(ev.t) >= 0)
    assert ev.t[0] >= 0 and ev.t[-1] <= 1_000_000_000
    assert np.all(ev.t % 1000 == 0)  # µs timestamps
    assert int(ev.x.max()) < 240 and int(ev.y.max()) < 180
    # events cover the image, not one corner
    assert np.ptp(ev.x) > 200 and np.ptp(ev.y) > 150
    assert (rotation.calib.width, rotation.calib.height) == (240, 180)
    assert rotation.calib.fx == pytest.approx(199, abs=1)


def test_refractory_period_is_respected(quiet_rotation: Sequence) -> None:
    ev = quiet_rotation.events
    pix = ev.y.astype(np.int64) * 240 + ev.x
    order = np.lexsort((ev.t, pix))
    same = pix[order][1:] == pix[order][:-1]
    dt = np.diff(ev.t[order])[same]
    refractory_ns = QUIET.refractory_s * 1e9
    assert dt.min() >= refractory_ns - 1000  # 1 µs timestamp quantum
    # and the refractory period matters: many pixels fire right after it
    assert np.mean(dt < 2 * refractory_ns) > 0.05


def test_noise_adds_events_everywhere() -> None:
    noisy = simulate('rotation', 0.3, seed=12, config=SimulatorConfig(
        noise_rate_hz=5.0, hot_pixels=0))
    quiet = simulate('rotation', 0.3, seed=12, config=QUIET)
    extra = len(noisy.events) - len(quiet.events)
    expected = 5.0 * 240 * 180 * 0.3
    assert abs(extra - expected) < 0.15 * expected


def test_hot_pixels_fire_at_their_expected_rate() -> None:
    """2000 hot pixels at a nominal 50 Hz for 0.3 s: each fires at 0.3-2.0 times the nominal
    rate, 1.15 times on average, so 2000 * 50 * 1.15 * 0.3 = 34500 events beyond the quiet
    sensor's (the spread of 2000 rate factors and the Poisson counts: about 1.2 %)."""
    cfg = replace(QUIET, hot_pixels=2000, hot_pixel_rate_hz=50.0)
    assert cfg.hot_events_per_s == pytest.approx(2000 * 50.0 * 1.15)
    hot = simulate('rotation', 0.3, seed=12, config=cfg)
    quiet = simulate('rotation', 0.3, seed=12, config=QUIET)
    extra = len(hot.events) - len(quiet.events)
    assert extra == pytest.approx(34500, rel=0.04)


def test_gyro_integrates_to_ground_truth(quiet_rotation: Sequence) -> None:
    imu, gt = quiet_rotation.imu, quiet_rotation.groundtruth
    assert imu is not None and gt is not None
    assert len(imu) == 501 and len(gt) == 501  # 0.5 s at 1 kHz each
    R = np.eye(3)
    dt = np.diff(imu.t) * 1e-9
    for k in range(len(dt)):
        w = 0.5 * (imu.gyro[k] + imu.gyro[k + 1])  # trapezoid, body frame
        R = R @ so3_exp(w * dt[k])
    Rgt = quat_to_matrix(gt.quat)
    R_true = Rgt[0].T @ Rgt[-1]
    err = np.degrees(rotation_angle(R.T @ R_true))
    total = np.degrees(rotation_angle(R_true))
    assert total > 5.0
    assert err < 0.05 * total


def test_accelerometer_measures_gravity_at_rest() -> None:
    seq = simulate('arm', 0.3, seed=3, config=QUIET)  # the arm holds still for 0.5 s
    assert seq.imu is not None
    acc = seq.imu.acc
    # gravity plus the arm's mm-level wobble (up to ~0.3 m/s^2)
    np.testing.assert_allclose(np.linalg.norm(acc, axis=1), 9.81, atol=0.35)
    assert abs(float(np.mean(np.linalg.norm(acc, axis=1))) - 9.81) < 0.25
    # looking down: the reaction to gravity points up, against the optical axis (-z)
    assert np.all(acc[:, 2] < -9.4)
    assert (seq.calib.width, seq.calib.height) == (640, 480)


def test_same_seed_same_sequence_other_seed_differs() -> None:
    a = simulate('translation', 0.2, seed=5)
    b = simulate('translation', 0.2, seed=5)
    c = simulate('translation', 0.2, seed=6)
    assert _checksum(a) == _checksum(b)
    assert a.imu is not None and b.imu is not None
    np.testing.assert_array_equal(a.imu.gyro, b.imu.gyro)
    assert _checksum(a) != _checksum(c)


def test_translation_moves_and_changes_depth() -> None:
    seq = simulate('translation', 0.2, seed=7)
    info = describe_motion(seq)
    assert info['peak_m_s'] > 0.1
    assert info['events_per_s'] > 5e4


def test_optical_axis_estimate_reads_position_pan_roll_and_depth() -> None:
    # wall z = 0.8; poses: start, 5 cm right, 10 cm closer, 1 deg pan, 30 deg roll
    pan = np.radians(1.0)
    R = np.stack([np.eye(3), np.eye(3), np.eye(3), euler_ptr_to_matrix(pan, 0.0, 0.0),
                  rot_z(np.radians(30.0))])
    pos = np.array([[0, 0, 0], [0.05, 0, 0], [0, 0, 0.1], [0, 0, 0], [0, 0, 0]], float)
    gt = Trajectory(np.arange(5, dtype=np.int64) * 10**8, pos, matrix_to_quat(R))
    h, v, r, z = optical_axis_estimate(gt, PLANE_Z['translation'])
    np.testing.assert_allclose(h[1], 0.05, atol=1e-12)            # translation is read as is
    np.testing.assert_allclose(z[2], -np.log(0.7 / 0.8), atol=1e-12)   # closer: magnified
    # a pan moves the axis point like a sideways translation of 0.8 tan(1 deg) = 1.4 cm
    assert abs(h[3]) == pytest.approx(0.8 * np.tan(pan), rel=1e-9)
    np.testing.assert_allclose(r, [0, 0, 0, 0, np.radians(30.0)], atol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-12)


def test_bad_kind_and_duration() -> None:
    with pytest.raises(ConfigError, match='unknown simulation kind'):
        simulate('spin', 1.0, seed=1)
    with pytest.raises(ConfigError, match='must be positive'):
        simulate('rotation', 0.0, seed=1)
    with pytest.raises(ConfigError, match='contrast_threshold'):
        SimulatorConfig(contrast_threshold=-1.0)


def test_simulate_cli_writes_readable_dataset(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'seq'
    assert main(['simulate', str(out), '--kind', 'rotation', '--seconds', '0.2',
                 '--seed', '4']) == 0
    assert 'events' in capsys.readouterr().out
    assert read_sensor_size(out) == (240, 180)
    assert read_calib(out).fx == pytest.approx(199.1)
    assert len(read_groundtruth(out)) == 201  # 0.2 s at 1 kHz
    assert len(read_imu(out)) == 201
    assert main(['simulate', str(out), '--seconds', '0.1']) == 3  # refuses to overwrite
