"""Gyro integration between frame times (core/imu.py)."""

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
    g = GyroIntegrator(imu(t, w))
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
    np.testing.assert_allclose(GyroIntegrator(imu(t, w), rot).angle_at(1_000_000_000),
                               [0.0, 1.0, 0.0], atol=1e-12)


def test_bad_imu_data() -> None:
    with pytest.raises(DatasetError, match='at least 2'):
        GyroIntegrator(imu(np.array([0]), np.zeros((1, 3))))
    with pytest.raises(DatasetError, match='increasing'):
        GyroIntegrator(imu(np.array([0, 5, 5]), np.zeros((3, 3))))
    with pytest.raises(DatasetError, match='3x3'):
        GyroIntegrator(imu(np.array([0, 5]), np.zeros((2, 3))), np.eye(2))
