"""Readouts → REP-103/105 poses with covariance (core/odometry.py), known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrn_vo_ros.core.odometry.odometry import (
    OdometryConfig,
    quat_from_matrix,
    R_BASE_OPTICAL,
    readout_to_pose,
    rot_x,
    rot_y,
    rot_z,
)
from hrn_vo_ros.errors import ConfigError

F = 80.0
FULL = {'h': 1.0, 'v': 1.0, 'r': 1.0, 'z': 1.0}


def q_axis(axis: tuple[float, float, float], angle: float) -> np.ndarray:
    return np.array([*(math.sin(angle / 2) * np.asarray(axis)), math.cos(angle / 2)])


def test_quaternion_of_elementary_rotations() -> None:
    for R, axis in ((rot_x, (1, 0, 0)), (rot_y, (0, 1, 0)), (rot_z, (0, 0, 1))):
        for a in (0.3, -2.0, 3.0):
            np.testing.assert_allclose(quat_from_matrix(R(a)), q_axis(axis, a) * np.sign(
                math.cos(a / 2)), atol=1e-12)


@pytest.mark.parametrize(('h', 'v', 'r', 'axis', 'angle'), [
    (F * math.tan(0.1), 0.0, 0.0, (0, 0, 1), -0.1),   # pan right = negative yaw (y is left)
    (0.0, F * math.tan(0.2), 0.0, (0, 1, 0), 0.2),    # looking down = positive pitch
    (0.0, 0.0, 0.4, (1, 0, 0), 0.4),                  # optical roll = roll about x forward
])
def test_rotation_model_in_base_link(h: float, v: float, r: float,
                                     axis: tuple[float, float, float], angle: float) -> None:
    cfg = OdometryConfig(focal_length_px=F)
    pose = readout_to_pose(cfg, 5, h, v, r, None, FULL)
    assert pose.t_ns == 5
    np.testing.assert_allclose(pose.quat, q_axis(axis, angle), atol=1e-12)
    np.testing.assert_allclose(pose.position, 0.0)


def test_rotation_model_in_the_camera_frame() -> None:
    cfg = OdometryConfig(focal_length_px=F, child_frame='camera')
    pose = readout_to_pose(cfg, 0, F * math.tan(0.1), 0.0, 0.0, None, FULL)
    np.testing.assert_allclose(pose.quat, q_axis((0, 1, 0), 0.1), atol=1e-12)


def test_translation_model_and_covariance() -> None:
    cfg = OdometryConfig(motion_model='translation', focal_length_px=F, depth_m=2.0,
                         sigma_px=0.5, unobserved_variance=99.0)
    cam = readout_to_pose(OdometryConfig(motion_model='translation', focal_length_px=F,
                                         depth_m=2.0, child_frame='camera'),
                          0, F, -F / 2, 0.0, math.log(2.0), FULL)
    np.testing.assert_allclose(cam.position, [2.0, -1.0, 1.0])
    base = readout_to_pose(cfg, 0, F, -F / 2, 0.0, math.log(2.0), {**FULL, 'h': 0.5})
    np.testing.assert_allclose(base.position, R_BASE_OPTICAL @ [2.0, -1.0, 1.0])
    np.testing.assert_allclose(base.position, [1.0, -2.0, 1.0])
    cov = base.covariance
    # base y is optical x: sigma = 0.5 px / confidence 0.5 → 1 px → 1 * d / f metres
    assert cov[1, 1] == pytest.approx((1.0 * 2.0 / F) ** 2)
    assert cov[2, 2] == pytest.approx((0.5 * 2.0 / F) ** 2)        # base z is optical -y
    assert cov[0, 0] == pytest.approx((2.0 * 0.5 * 0.01) ** 2)     # d e^-z sigma_z
    assert cov[4, 4] == 99.0 and cov[5, 5] == 99.0                 # pitch, yaw unobserved
    np.testing.assert_allclose(cov, cov.T)


def test_low_confidence_inflates_and_floors() -> None:
    cfg = OdometryConfig(focal_length_px=F, min_confidence=0.1)
    sure = readout_to_pose(cfg, 0, 1.0, 1.0, 0.1, None, FULL).covariance
    unsure = readout_to_pose(cfg, 0, 1.0, 1.0, 0.1, None, {'h': 0.5, 'v': -1.0}).covariance
    assert unsure[5, 5] == pytest.approx(4 * sure[5, 5], rel=1e-9)    # yaw from h
    assert unsure[4, 4] == pytest.approx(100 * sure[4, 4], rel=1e-9)  # floor 0.1 on v
    assert unsure[3, 3] == pytest.approx(100 * sure[3, 3], rel=1e-9)  # r missing → floor


def test_config_rejects_bad_values() -> None:
    with pytest.raises(ConfigError, match='motion_model'):
        OdometryConfig(motion_model='spiral')
    with pytest.raises(ConfigError, match='focal_length_px'):
        OdometryConfig(focal_length_px=0.0)
