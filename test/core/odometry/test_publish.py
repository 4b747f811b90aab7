"""The publisher side of the odometry (core/odometry/publish.py), without ROS."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.odometry import (
    mount_transform,
    OdometryConfig,
    readout_to_pose,
    twist_between,
)
from hrn_vo_ros.core.odometry.publish import (
    child_frame_id,
    GyroGate,
    imu_frame_warning,
    OdometryComposer,
    size_mismatch_text,
    static_frames,
    with_covariance_scale,
)

ODO = OdometryConfig(focal_length_px=80.0)
CONF = {'h': 1.0, 'v': 1.0, 'r': 1.0}


def est(k: int, quality: float = 1.0, state: str = 'tracking', z: float = 0.0) -> Estimate:
    return Estimate(10**9 + k * 10**7, float(k), 0.0, 0.0, z, confidence=CONF,
                    quality=quality, state=state)


def compose(c: OdometryComposer, k: int, **kw: object) -> tuple[np.ndarray, object]:
    e = est(k, **kw)  # type: ignore[arg-type]
    out = c.compose(e.t_ns, e, ODO, with_z=False, lost_variance=1e6, min_quality=0.05)
    return out.pose.covariance, out.twist


def test_covariance_follows_quality_floor_and_lost() -> None:
    c = OdometryComposer()
    raw = [readout_to_pose(ODO, 10**9 + k * 10**7, float(k), 0.0, 0.0, None, CONF)
           for k in range(5)]
    cov, twist = compose(c, 0)
    assert twist is None
    np.testing.assert_allclose(cov, raw[0].covariance)
    cov, twist = compose(c, 1, quality=0.5, state='degraded')
    np.testing.assert_allclose(cov, 4 * raw[1].covariance)
    tw = twist_between(raw[0], raw[1], ODO.unobserved_variance)
    np.testing.assert_allclose(twist.covariance, 4 * tw.covariance)  # type: ignore[attr-defined]
    cov, _ = compose(c, 2, quality=0.01, state='degraded')          # floor 0.05: x 400
    np.testing.assert_allclose(cov, 400 * raw[2].covariance)
    cov, twist = compose(c, 3, quality=0.9, state='lost')
    assert np.array_equal(cov, np.eye(6) * 1e6)
    assert np.array_equal(twist.covariance, np.eye(6) * 1e6)        # type: ignore[attr-defined]
    assert c.status() == ('error', 'tracking lost (quality 0.90)')
    compose(c, 4, quality=float('nan'), state='degraded')            # NaN quality: the floor
    assert c.status()[0] == 'warn'
    values = dict(c.diagnostic_values())
    assert values['confidence_h'] == '1.000' and values['tracking_state'] == 'degraded'


def test_the_twist_restarts_and_z_is_read_out_only_when_asked() -> None:
    c = OdometryComposer()
    compose(c, 0)
    c.restart()
    assert compose(c, 1)[1] is None
    e = est(2, z=0.3)
    out = c.compose(e.t_ns, e, ODO, with_z=True, lost_variance=1e6, min_quality=0.05)
    assert out.values == {'h': 2.0, 'v': 0.0, 'r': 0.0, 'z': 0.3}
    assert compose(c, 3)[1] is not None


def test_with_covariance_scale_leaves_full_quality_alone() -> None:
    pose = readout_to_pose(ODO, 0, 1.0, 0.0, 0.0, None, CONF)
    same, twist = with_covariance_scale(pose, None, 1.0, 'tracking', lost_variance=1e6,
                                        min_quality=0.05)
    assert same is pose and twist is None
    higher, _ = with_covariance_scale(pose, None, 2.0, 'tracking', lost_variance=1e6,
                                      min_quality=0.05)        # quality above 1 counts as 1
    assert higher is pose


def test_the_focal_length_of_the_resonator_wins_and_warns_once() -> None:
    c = OdometryComposer()
    odo, warning = c.odometry(ODO, 0.0)
    assert odo is ODO and warning is None
    odo, warning = c.odometry(ODO, 100.0)
    assert odo.focal_length_px == 100.0 and warning is not None and 'focal_px 100' in warning
    again, warning = c.odometry(ODO, 100.0)
    assert again is odo and warning is None
    assert c.odometry(ODO, 80.0) == (ODO, None)


def test_static_frames_and_the_child_frame() -> None:
    R_ci = tuple(float(v) for v in np.eye(3)[[1, 0, 2]].ravel())
    frames = static_frames(ODO, R_ci, base='base', camera='cam')
    assert [(p, c) for p, c, _, _ in frames] == [('base', 'cam')]
    R, t = mount_transform(ODO)
    np.testing.assert_array_equal(frames[0][2], R)
    frames = static_frames(ODO, R_ci, base='base', camera='cam', imu='imu')
    assert [(p, c) for p, c, _, _ in frames] == [('base', 'cam'), ('cam', 'imu')]
    np.testing.assert_array_equal(frames[1][2], np.eye(3)[[1, 0, 2]])
    np.testing.assert_array_equal(frames[1][3], np.zeros(3))       # the IMU at the camera
    assert child_frame_id(ODO, 'base', 'cam') == 'base'
    cam = OdometryConfig(child_frame='camera')
    assert child_frame_id(cam, 'base', 'cam') == 'cam'


def test_gyro_gate_holds_frames_until_covered_bounded_and_forced() -> None:
    gate = GyroGate(tuple(float(v) for v in np.eye(3).ravel()), max_samples=100,
                    max_pending=2)
    image = np.zeros((2, 2), np.uint8)
    gate.add(10, image, 0.0)
    assert list(gate.drain(force=False)) == []
    for t in (0, 5, 20):
        gate.add_gyro(t, np.zeros(3), 1.0)
    assert [t for t, _ in gate.drain(force=False)] == [10]
    for t in (30, 40, 50):
        gate.add(t, image, 2.0)
    assert [t for t, _ in gate.drain(force=False)] == [30]   # over the bound: the oldest
    assert len(gate) == 2
    assert not gate.stalled(2.4, 0.5) and gate.stalled(3.1, 0.5)
    assert [t for t, _ in gate.drain(force=True)] == [40, 50] and not gate.stalled(9.0, 0.5)
    old = gate.gyro
    assert gate.new_gyro() is gate.gyro and gate.gyro is not old and len(gate.gyro) == 0


def test_gyro_gate_stalls_on_its_oldest_frame_and_the_imu_and_takes_a_new_rotation() -> None:
    """Stalled: frames wait and the oldest of them and the IMU are both more than the
    timeout old (strictly); a new gyro may take a new IMU -> camera rotation."""
    image = np.zeros((2, 2), np.uint8)
    gate = GyroGate(tuple(float(v) for v in np.eye(3).ravel()), max_samples=100,
                    max_pending=5)
    gate.add_gyro(0, np.zeros(3), 1.0)
    gate.add(10, image, 2.0)
    gate.add(20, image, 2.9)
    assert not gate.stalled(2.5, 0.5) and gate.stalled(3.2, 0.5)   # the oldest is 1.2 s old
    gate.add_gyro(5, np.zeros(3), 2.8)
    assert not gate.stalled(3.2, 0.5)                              # the IMU moved 0.4 s ago
    gate.new_gyro(tuple(float(v) for v in np.eye(3)[[1, 0, 2]].ravel()))
    gate.add_gyro(0, np.array([1.0, 0.0, 0.0]), 4.0)
    gate.add_gyro(10**9, np.array([1.0, 0.0, 0.0]), 4.0)
    assert gate.gyro.increment(0) is None
    np.testing.assert_allclose(gate.gyro.increment(10**9), [0.0, 1.0, 0.0])   # x -> y


def test_check_texts() -> None:
    text = size_mismatch_text(128, 96, 96, 72)
    assert 'frames are 128x96, width/height are 96x72' in text
    assert 'width: 128 and height: 96 (or frame_size: frames)' in text
    assert imu_frame_warning('imu_link', '') is None
    assert imu_frame_warning('imu_link', 'imu_link') is None
    warning = imu_frame_warning('imu', 'imu_link')
    assert warning is not None and "'imu'" in warning and "'imu_link'" in warning


def test_twist_sign_of_a_pan() -> None:
    c = OdometryComposer()
    compose(c, 2)
    _, twist = compose(c, 3)
    yaw_rate = (math.atan(2 / 80) - math.atan(3 / 80)) / 0.01
    assert twist.angular[2] == pytest.approx(yaw_rate, rel=1e-6)  # type: ignore[attr-defined]
