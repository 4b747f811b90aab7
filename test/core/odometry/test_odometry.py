"""Readouts → REP-103/105 poses with covariance (core/odometry.py), known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hrn_vo_ros.core.odometry.odometry import (
    camera_pose,
    mount_transform,
    OdometryConfig,
    OdomPose,
    quat_from_matrix,
    R_BASE_OPTICAL,
    readout_to_pose,
    rot_x,
    rot_y,
    rot_z,
    twist_between,
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


@pytest.mark.parametrize(('h', 'v', 'axis', 'angle'), [
    (F * 0.3, 0.0, (0, 1, 0), 0.3),                          # pan: angle = h / f (no atan)
    (0.0, F * 0.2, (1, 0, 0), -0.2),                         # tilt: image down = -x rotation
    (F * 0.4, F * 0.4, (-0.5 ** 0.5, 0.5 ** 0.5, 0), 0.4 * 2 ** 0.5),  # one swing, not two
])
def test_equidistant_rotation_is_one_swing_of_the_image_distance(
        h: float, v: float, axis: tuple[float, float, float], angle: float) -> None:
    """An equidistant frame shifted by (h, v) saw the optical axis swing by |(h, v)| / f about
    (-v, h, 0) (camera frame: x right, y down): hand-computed axis-angle quaternions."""
    cfg = OdometryConfig(focal_length_px=F, child_frame='camera', projection='equidistant')
    pose = readout_to_pose(cfg, 0, h, v, 0.0, None, FULL)
    np.testing.assert_allclose(pose.quat, q_axis(axis, angle), atol=1e-12)
    # with a roll the twist comes first: R = swing @ Rz(r)
    rolled = readout_to_pose(cfg, 0, h, v, 0.25, None, FULL)
    q_s, q_r = q_axis(axis, angle), q_axis((0, 0, 1), 0.25)
    x1, y1, z1, w1 = q_s
    x2, y2, z2, w2 = q_r
    want = np.array([w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2])
    np.testing.assert_allclose(rolled.quat, want * np.sign(want[3]), atol=1e-12)


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
    for xyz, rpy in (((0.0, 0.0), (0.0, 0.0, 0.0)), ((0.0, 0.0, 0.0), (0.0,) * 4)):
        with pytest.raises(ConfigError, match='3 values each'):
            OdometryConfig(mount_xyz=xyz, mount_rpy=rpy)


def test_planar_model_in_base_link_and_camera() -> None:
    cam_cfg = OdometryConfig(motion_model='planar', focal_length_px=F, depth_m=2.0,
                             child_frame='camera', sigma_px=0.5, unobserved_variance=99.0)
    cam = readout_to_pose(cam_cfg, 0, F, -F / 2, 0.3, 0.5, FULL)     # z ignored
    np.testing.assert_allclose(cam.position, [2.0, -1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(cam.quat, q_axis((0, 0, 1), 0.3), atol=1e-12)
    cov = cam.covariance
    assert cov[0, 0] == pytest.approx((0.5 * 2.0 / F) ** 2)            # x from h
    assert cov[2, 2] == 99.0 and cov[3, 3] == 99.0 and cov[4, 4] == 99.0
    assert cov[5, 5] == pytest.approx(OdometryConfig().sigma_roll_rad ** 2)
    base = readout_to_pose(OdometryConfig(motion_model='planar', focal_length_px=F,
                                          depth_m=2.0), 0, F, -F / 2, 0.3, 0.5, FULL)
    # optical x (right) = base -y, optical y (down) = base -z, optical z = base x
    np.testing.assert_allclose(base.position, [0.0, -2.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(base.quat, q_axis((1, 0, 0), 0.3), atol=1e-12)
    assert base.covariance[0, 0] == 1e4                   # base x = optical z: unobserved
    assert base.covariance[1, 1] == pytest.approx((0.5 * 2.0 / F) ** 2)
    assert base.covariance[3, 3] == pytest.approx(OdometryConfig().sigma_roll_rad ** 2)


DOWN = OdometryConfig(motion_model='planar', focal_length_px=F, depth_m=2.0,
                      mount_xyz=(0.5, 0.0, 1.0), mount_rpy=(0.0, math.pi / 2, 0.0))


def test_mount_transform_of_a_camera_looking_down() -> None:
    R, t = mount_transform(DOWN)
    # pitch 90 deg: the view (optical z) points down, image right (optical x) to the right
    # of the robot (-y), image down (optical y) backwards (-x)
    np.testing.assert_allclose(R, [[0, -1, 0], [-1, 0, 0], [0, 0, -1]], atol=1e-15)
    np.testing.assert_allclose(t, [0.5, 0.0, 1.0])
    R0, t0 = mount_transform(OdometryConfig())
    np.testing.assert_allclose(R0, R_BASE_OPTICAL)
    np.testing.assert_allclose(t0, 0.0)
    R_yaw, _ = mount_transform(OdometryConfig(mount_rpy=(0.0, 0.0, math.pi / 2)))
    np.testing.assert_allclose(R_yaw[:, 2], [0, 1, 0], atol=1e-15)       # looking left


def test_mounted_camera_moves_base_link() -> None:
    # the camera slides 1 m along image x (to the robot's right): base_link moves -y, the
    # mount offset cancels
    slide = readout_to_pose(DOWN, 0, F / 2, 0.0, 0.0, None, FULL)
    np.testing.assert_allclose(slide.position, [0.0, -1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(slide.quat, [0, 0, 0, 1], atol=1e-15)
    # the camera turns +90 deg about its axis (pointing down): base_link yaws -90 deg about
    # the camera's vertical axis, 0.5 m ahead of it: from (0, 0) to (0.5, 0.5)
    turn = readout_to_pose(DOWN, 0, 0.0, 0.0, math.pi / 2, None, FULL)
    np.testing.assert_allclose(turn.position, [0.5, 0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(turn.quat, q_axis((0, 0, 1), -math.pi / 2), atol=1e-12)


def pose(t_s: float, R: np.ndarray, p: list[float], var: list[float]) -> OdomPose:
    return OdomPose(int(round(t_s * 1e9)), np.asarray(p, np.float64), quat_from_matrix(R),
                    np.diag(var))


def test_twist_between_is_in_the_child_frame() -> None:
    R0 = rot_x(math.pi / 2)
    R1 = R0 @ rot_z(0.1)                        # turned 0.1 rad about its own z in 0.1 s
    p0 = [1.0, 2.0, 3.0]
    p1 = list(np.asarray(p0) + R1 @ [0.05, 0.0, 0.0])    # 5 cm along its own x
    tw = twist_between(pose(1.0, R0, p0, [0.0] * 6), pose(1.1, R1, p1, [0.0] * 6), 7.0)
    np.testing.assert_allclose(tw.linear, [0.5, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(tw.angular, [0.0, 0.0, 1.0], atol=1e-9)


def test_twist_covariance_and_no_time_between() -> None:
    R = rot_x(math.pi / 2) @ rot_z(math.pi / 2)  # child x, y, z = odom z, -x, -y
    var = [1e-4, 2e-4, 3e-4, 4e-4, 5e-4, 6e-4]
    a, b = pose(1.0, R, [0, 0, 0], var), pose(1.1, R, [0.1, 0, 0], var)
    tw = twist_between(a, b, 7.0)
    np.testing.assert_allclose(tw.linear, [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(tw.angular, 0.0, atol=1e-12)
    # both poses' variances added, divided by dt^2 = 0.01, in the child's axes
    np.testing.assert_allclose(np.diag(tw.covariance), [0.06, 0.02, 0.04, 0.12, 0.08, 0.1],
                               rtol=1e-9)
    same = twist_between(b, b, 7.0)
    np.testing.assert_array_equal(same.linear, 0.0)
    np.testing.assert_array_equal(same.covariance, np.eye(6) * 7.0)


@pytest.mark.parametrize('axis', [(0.2, 0.9, -0.3), (-0.7, 0.1, 0.7), (0.1, -0.2, 0.97),
                                  (1.0, 1.0, 1.0), (0.9, 0.3, 0.1)])
@pytest.mark.parametrize('angle', [2.1, 2.9, math.pi, -2.5])
def test_quaternion_of_large_turns_about_oblique_axes(axis: tuple[float, float, float],
                                                      angle: float) -> None:
    """Turns past 90° (trace <= 0: every branch of Shepperd's method, with off-diagonal
    terms) against scipy's conversion, an independent implementation; w >= 0."""
    rv = np.asarray(axis) / np.linalg.norm(axis) * angle
    R = Rotation.from_rotvec(rv).as_matrix()
    q = quat_from_matrix(R)
    ref = Rotation.from_rotvec(rv).as_quat()          # (x, y, z, w)
    ref = -ref if ref[3] < 0 else ref
    if abs(ref[3]) < 1e-12:                           # a half turn: both signs are w = 0
        ref = ref * np.sign(np.dot(ref, q))
    np.testing.assert_allclose(q, ref, atol=1e-12)
    assert q[3] >= 0.0


def test_covariances_of_each_motion_model_by_hand() -> None:
    """sigma_px 0.5, scale 2 (so 1 px), f 80, full confidence, h 30, v -20: pinhole
    d pan / dh = f / (f^2 + (2 h)^2) = 80 / 10000, d tilt / dv = 80 / 8000; equidistant
    1 / f; planar at 2 m: 1 px x 2 m / 80 px."""
    kw = {'focal_length_px': 80.0, 'scale': 2.0, 'sigma_px': 0.5, 'sigma_roll_rad': 0.02}
    _, _, cov = camera_pose(OdometryConfig(**kw), 30.0, -20.0, 0.1, None, FULL)
    assert np.diag(cov)[3:] == pytest.approx([0.01 ** 2, 0.008 ** 2, 0.02 ** 2], rel=1e-12)
    _, _, cov = camera_pose(OdometryConfig(projection='equidistant', **kw), 30.0, -20.0, 0.1,
                            None, FULL)
    assert np.diag(cov)[3:5] == pytest.approx([0.0125 ** 2] * 2, rel=1e-12)
    _, _, cov = camera_pose(OdometryConfig(motion_model='planar', depth_m=2.0, **kw), 30.0,
                            -20.0, 0.1, None, FULL)
    assert np.diag(cov)[[0, 1, 5]] == pytest.approx([0.025 ** 2, 0.025 ** 2, 0.02 ** 2],
                                                     rel=1e-12)
