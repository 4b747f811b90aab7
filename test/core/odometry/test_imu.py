"""Gyro integration between frame times (core/odometry/imu.py), for logs and streams alike."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.events.sequence import ImuData
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.errors import DatasetError


def imu(t: np.ndarray, gyro: np.ndarray) -> ImuData:
    return ImuData(t=t.astype(np.int64), acc=np.zeros((len(t), 3)), gyro=gyro)


def test_integrates_a_linear_ramp_exactly_between_samples() -> None:
    t = np.arange(0, 1_000_000_001, 1_000_000)                  # 1 kHz for 1 s
    w = np.stack([np.full(len(t), 0.5), 2.0 * t * 1e-9, np.zeros(len(t))], axis=1)
    g = GyroIntegrator.from_imu(imu(t, w))
    q = np.array([0, 123_456_789, 500_000_500, 1_000_000_000])
    ang = g.angle_at(q)
    s = q * 1e-9
    np.testing.assert_allclose(ang[:, 0], 0.5 * s, atol=1e-12)
    np.testing.assert_allclose(ang[:, 1], s ** 2, atol=1e-9)   # ∫ 2 t dt, trapezoid exact
    d = g.deltas(q)
    np.testing.assert_allclose(d[0], 0.0)
    np.testing.assert_allclose(d[1:].sum(axis=0), ang[-1] - ang[0], atol=1e-12)
    assert g.angle_at(2_000_000_000)[0] == pytest.approx(0.5)    # clamped to the IMU span


def test_camera_from_imu_rotates_the_axes() -> None:
    t = np.arange(0, 11) * 100_000_000
    w = np.tile([1.0, 0.0, 0.0], (len(t), 1))
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])   # x_imu -> y_cam
    np.testing.assert_allclose(GyroIntegrator.from_imu(imu(t, w), rot).angle_at(1_000_000_000),
                               [0.0, 1.0, 0.0], atol=1e-12)


def test_bad_imu_data() -> None:
    with pytest.raises(DatasetError, match='at least 2'):
        GyroIntegrator.from_imu(imu(np.array([0]), np.zeros((1, 3))))
    with pytest.raises(DatasetError, match='increasing'):
        GyroIntegrator.from_imu(imu(np.array([0, 5, 5]), np.zeros((3, 3))))
    with pytest.raises(DatasetError, match='3x3'):
        GyroIntegrator.from_imu(imu(np.array([0, 5]), np.zeros((2, 3))), np.eye(2))
    with pytest.raises(DatasetError, match='3x3'):
        GyroIntegrator(np.eye(2))


@pytest.mark.parametrize('rot', [np.eye(3), np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]])])
def test_streaming_angles_equal_batch_bit_for_bit(rng: np.random.Generator,
                                                  rot: np.ndarray) -> None:
    t_imu = 10**12 + np.cumsum(rng.integers(800_000, 1_200_000, 400)).astype(np.int64)
    gyro = rng.normal(size=(400, 3))
    frames = np.sort(rng.integers(t_imu[0] - 5_000_000, t_imu[-1] + 5_000_000, 120))
    batch = GyroIntegrator.from_imu(ImuData(t_imu, np.zeros_like(gyro), gyro), rot)
    buf = GyroIntegrator(rot, max_samples=100)
    got, want, j = [], [], 0
    for t in frames:
        while j < len(t_imu) and not buf.covers(int(t)):
            buf.add(int(t_imu[j]), gyro[j])
            j += 1
        got.append(buf.angle_at(int(t)))
        want.append(batch.angle_at(int(t)))        # per frame, as hrn-vo run calls it
        buf.trim(int(t))
    np.testing.assert_array_equal(np.array(got), np.array(want))
    assert len(buf) < 100


def test_log_and_stream_increments_are_the_same_call_and_the_same_bits(
        rng: np.random.Generator) -> None:
    """``increment`` of a whole log equals that of a stream fed sample by sample (and of a log
    appended in chunks), frame by frame."""
    t_imu = np.cumsum(rng.integers(900_000, 1_100_000, 300)).astype(np.int64)
    gyro = rng.normal(size=(300, 3))
    frames = np.sort(rng.integers(t_imu[0], t_imu[-1], 80))
    log = GyroIntegrator.from_imu(ImuData(t_imu, np.zeros_like(gyro), gyro))
    chunks = GyroIntegrator()
    for part in np.array_split(np.arange(300), 7):
        chunks.extend(t_imu[part], gyro[part])
    stream = GyroIntegrator(max_samples=50)
    j = 0
    for k, t in enumerate(frames):
        while j < len(t_imu) and not stream.covers(int(t)):
            stream.add(int(t_imu[j]), gyro[j])
            j += 1
        a, b, c = log.increment(int(t)), chunks.increment(int(t)), stream.increment(int(t))
        stream.trim(int(t))
        if k == 0:
            assert a is None and b is None and c is None
            continue
        assert a is not None and b is not None and c is not None
        np.testing.assert_array_equal(b, a)
        np.testing.assert_array_equal(c, a)
    assert len(log) == 300 and len(stream) <= 50
    with pytest.raises(DatasetError, match='does not increase'):
        chunks.extend(t_imu[-2:], gyro[-2:])


def test_bad_samples_are_refused() -> None:
    buf = GyroIntegrator()
    buf.add(10, np.zeros(3))
    with pytest.raises(DatasetError, match='not finite'):
        buf.add(20, np.array([0.0, np.nan, 0.0]))
    with pytest.raises(DatasetError, match='does not increase'):
        buf.add(10, np.zeros(3))
    np.testing.assert_array_equal(buf.delta(0, 100), np.zeros(3))


def test_frames_after_the_last_sample_are_clamped() -> None:
    buf = GyroIntegrator()
    for k in range(5):
        buf.add(k * 10, np.array([0.0, 0.0, 1e9]))
    np.testing.assert_allclose(buf.delta(25, 200), [0, 0, 15.0])   # clamped at 40
    np.testing.assert_allclose(buf.angle_at(-5), [0, 0, 0])         # clamped at 0
    buf.trim(100)
    np.testing.assert_array_equal(buf.delta(100, 200), np.zeros(3))


def test_increments_are_differences_of_angles_and_survive_trim() -> None:
    buf = GyroIntegrator()
    for k in range(20):
        buf.add(k * 10, np.array([0.0, 1e9, 2e9]))        # 1 and 2 rad per ns
    assert buf.increment(25) is None                       # the first frame has no increment
    buf.trim(35)
    np.testing.assert_allclose(buf.increment(35), [0, 10.0, 20.0])
    buf.trim(150)                                          # the sample at 25 ns is gone
    np.testing.assert_allclose(buf.increment(150), [0, 115.0, 230.0])


def test_max_samples_drops_the_oldest() -> None:
    buf = GyroIntegrator(max_samples=4)
    for k in range(10):
        buf.add(k * 10, np.array([0.0, 0.0, 1e9]))
    assert len(buf) == 4
    np.testing.assert_allclose(buf.angle_at(0), [0, 0, 60.0])      # clamped at the oldest, 60
    np.testing.assert_allclose(buf.angle_at(90), [0, 0, 90.0])      # the integral is kept


def test_batches_must_start_after_the_last_sample() -> None:
    """A batch's first time equal to the last sample's is refused; steps of 1 ns are fine."""
    buf = GyroIntegrator()
    buf.extend(np.array([10, 20]), np.zeros((2, 3)))
    with pytest.raises(DatasetError, match='does not increase'):
        buf.extend(np.array([20, 30]), np.zeros((2, 3)))
    buf.extend(np.array([30, 31]), np.zeros((2, 3)))
    assert len(buf) == 4


def test_coverage_max_samples_and_trim_bounds_by_hand() -> None:
    """A sample exactly at a frame's time covers it; max_samples keeps exactly that many;
    trim keeps the sample at or before its time and at least two."""
    buf = GyroIntegrator(max_samples=5)
    assert not buf.covers(0)
    for k in range(5):                                    # 0 .. 40 ns at 1 rad per ns
        buf.add(k * 10, np.array([0.0, 0.0, 1e9]))
    assert buf.covers(40) and not buf.covers(41) and len(buf) == 5
    np.testing.assert_allclose(buf.angle_at(0), [0, 0, 0.0])       # nothing dropped yet
    buf.trim(20)                                          # 20, 30, 40 remain
    assert len(buf) == 3
    np.testing.assert_allclose(buf.angle_at(25), [0, 0, 25.0])
    buf.trim(35)                                          # 30, 40 remain
    assert len(buf) == 2
    np.testing.assert_allclose(buf.angle_at(35), [0, 0, 35.0])
    buf.trim(1000)                                        # never fewer than two
    assert len(buf) == 2
    three = GyroIntegrator()
    for k in range(3):
        three.add(k * 10, np.array([0.0, 0.0, 1e9]))
    three.trim(1000)
    assert len(three) == 2
    one = GyroIntegrator()
    one.add(10, np.zeros(3))
    assert one.covers(10)
