"""The streaming gyro buffer gives the batch integrator's increments (core/imubuffer.py)."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.events.sequence import ImuData
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.core.odometry.imubuffer import GyroBuffer
from hrn_vo_ros.errors import DatasetError


@pytest.mark.parametrize('rot', [np.eye(3), np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]])])
def test_streaming_angles_equal_batch_bit_for_bit(rng: np.random.Generator,
                                                  rot: np.ndarray) -> None:
    t_imu = 10**12 + np.cumsum(rng.integers(800_000, 1_200_000, 400)).astype(np.int64)
    gyro = rng.normal(size=(400, 3))
    frames = np.sort(rng.integers(t_imu[0] - 5_000_000, t_imu[-1] + 5_000_000, 120))
    batch = GyroIntegrator(ImuData(t_imu, np.zeros_like(gyro), gyro), rot)
    buf = GyroBuffer(rot, max_samples=100)
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


def test_bad_samples_are_refused() -> None:
    buf = GyroBuffer()
    buf.add(10, np.zeros(3))
    with pytest.raises(DatasetError, match='not finite'):
        buf.add(20, np.array([0.0, np.nan, 0.0]))
    with pytest.raises(DatasetError, match='does not increase'):
        buf.add(10, np.zeros(3))
    np.testing.assert_array_equal(buf.delta(0, 100), np.zeros(3))


def test_frames_after_the_last_sample_are_clamped() -> None:
    buf = GyroBuffer()
    for k in range(5):
        buf.add(k * 10, np.array([0.0, 0.0, 1e9]))
    np.testing.assert_allclose(buf.delta(25, 200), [0, 0, 15.0])   # clamped at 40
    np.testing.assert_allclose(buf.angle_at(-5), [0, 0, 0])         # clamped at 0
    buf.trim(100)
    np.testing.assert_array_equal(buf.delta(100, 200), np.zeros(3))


def test_increments_are_differences_of_angles_and_survive_trim() -> None:
    buf = GyroBuffer()
    for k in range(20):
        buf.add(k * 10, np.array([0.0, 1e9, 2e9]))        # 1 and 2 rad per ns
    assert buf.increment(25) is None                       # the first frame has no increment
    buf.trim(35)
    np.testing.assert_allclose(buf.increment(35), [0, 10.0, 20.0])
    buf.trim(150)                                          # the sample at 25 ns is gone
    np.testing.assert_allclose(buf.increment(150), [0, 115.0, 230.0])
