"""Message ↔ numpy conversions (io/ros_msgs.py), built without rclpy.init."""

from __future__ import annotations

import math

from event_camera_msgs.msg import EventPacket
import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Imu

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.live import Step
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.odometry import (
    mount_transform,
    OdometryConfig,
    OdomPose,
    readout_to_pose,
    Twist,
)
from hrn_vo_ros.core.odometry.publish import OdometryComposer, static_frames
from hrn_vo_ros.errors import DecodeError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.eventpacket import encode_evt3, encode_mono, PacketDecoder


def test_stamps_round_trip_exactly() -> None:
    for t in (0, 1, 999_999_999, 1_700_000_000_123_456_789):
        assert ros_msgs.stamp_to_ns(ros_msgs.ns_to_stamp(t)) == t
    with pytest.raises(DecodeError):
        ros_msgs.ns_to_stamp(-1)


def test_event_packet_decodes_and_unknown_encoding_fails(rng: np.random.Generator) -> None:
    ev = EventArray.from_arrays(np.arange(50) * 7 + 10**12, rng.integers(0, 240, 50),
                                rng.integers(0, 180, 50), rng.integers(0, 2, 50))
    base, payload = encode_mono(ev)
    msg = EventPacket(time_base=base, encoding='mono', events=payload.tobytes())
    got = ros_msgs.events_from_packet(msg, PacketDecoder())
    for a in ('t', 'x', 'y', 'p'):
        np.testing.assert_array_equal(getattr(got, a), getattr(ev, a))
    msg.encoding = 'libcaer_cmp'
    with pytest.raises(DecodeError, match='libcaer_cmp'):
        ros_msgs.events_from_packet(msg, PacketDecoder())


def test_frames_round_trip_and_bad_frames_fail(rng: np.random.Generator) -> None:
    img = (rng.random((72, 96)) < 0.3).astype(np.uint8)
    msg = ros_msgs.frame_to_image(img, 123_456, 'cam')
    assert (msg.encoding, msg.step, msg.header.frame_id) == ('mono8', 96, 'cam')
    assert set(np.unique(np.frombuffer(msg.data, np.uint8))) == {0, 255}
    t, back = ros_msgs.image_to_frame(msg)
    assert t == 123_456 and np.array_equal(back, img)
    msg.data = bytes(10)
    with pytest.raises(DecodeError, match='carries 10 bytes'):
        ros_msgs.image_to_frame(msg)
    grey = ros_msgs.float_image_to_mono8(np.linspace(0, 1, 96 * 72).reshape(72, 96), 0, 'c')
    with pytest.raises(DecodeError, match='0 or 255'):
        ros_msgs.image_to_frame(grey)


def test_imu_and_nan() -> None:
    m = Imu()
    m.header.stamp = ros_msgs.ns_to_stamp(5)
    m.angular_velocity.x, m.linear_acceleration.z = 0.5, 9.81
    t, gyro, acc = ros_msgs.imu_to_arrays(m)
    assert t == 5 and gyro.tolist() == [0.5, 0, 0] and acc.tolist() == [0, 0, 9.81]
    m.angular_velocity.y = math.nan
    with pytest.raises(DecodeError, match='not finite'):
        ros_msgs.imu_to_arrays(m)


def test_pose_messages_carry_the_pose() -> None:
    pose = readout_to_pose(OdometryConfig(focal_length_px=80.0), 7_000_000_001, 8.0, -4.0, 0.3,
                           None, {'h': 1.0, 'v': 0.5, 'r': 0.9})
    ps = ros_msgs.pose_to_pose_stamped(pose, 'odom')
    od = ros_msgs.pose_to_odometry(pose, 'odom', 'base_link', 1e4)
    tf = ros_msgs.pose_to_tf(pose, 'odom', 'base_link')
    q = [ps.pose.orientation.x, ps.pose.orientation.y, ps.pose.orientation.z,
         ps.pose.orientation.w]
    np.testing.assert_allclose(q, pose.quat)
    np.testing.assert_allclose(np.reshape(od.pose.covariance, (6, 6)), pose.covariance)
    assert od.twist.covariance[0] == 1e4 and od.child_frame_id == 'base_link'
    assert ros_msgs.stamp_to_ns(tf.transforms[0].header.stamp) == 7_000_000_001
    assert tf.transforms[0].transform.rotation.w == pytest.approx(pose.quat[3])


def test_readout_round_trip_and_diagnostics() -> None:
    msg = ros_msgs.readout_to_joint_state(42, {'h': 1.5, 'v': -2.0, 'r': 0.1}, {'h': 0.9})
    t, values, conf = ros_msgs.joint_state_to_readout(msg)
    assert (t, values) == (42, {'h': 1.5, 'v': -2.0, 'r': 0.1})
    assert conf['h'] == 0.9 and math.isnan(conf['v'])
    d = ros_msgs.diagnostics(1, 'n', 'hw', 'warn', 'm', [('frames', 3), ('rate', '1.0')])
    assert d.status[0].level == b'\x01'
    assert ros_msgs.diagnostic_values(d) == {'frames': '3', 'rate': '1.0'}


def test_camera_info_gives_the_plumb_bob_calibration_or_a_clear_error() -> None:
    k = [199.1, 0.0, 121.3, 0.0, 198.8, 89.6, 0.0, 0.0, 1.0]
    msg = CameraInfo(width=240, height=180, distortion_model='plumb_bob', k=k,
                     d=[-0.12, 0.03, 0.001, 0.0, 0.0])
    c = ros_msgs.camera_info_to_calibration(msg)
    assert (c.width, c.height, c.fx, c.fy, c.cx, c.cy) == (240, 180, 199.1, 198.8, 121.3, 89.6)
    assert c.dist == (-0.12, 0.03, 0.001, 0.0, 0.0)
    short = CameraInfo(width=240, height=180, distortion_model='plumb_bob', k=k, d=[-0.1, 0.02])
    assert ros_msgs.camera_info_to_calibration(short).dist == (-0.1, 0.02, 0.0, 0.0, 0.0)
    pinhole = CameraInfo(width=240, height=180, k=k)
    assert ros_msgs.camera_info_to_calibration(pinhole).dist == (0.0,) * 5
    with pytest.raises(DecodeError, match='not calibrated'):
        ros_msgs.camera_info_to_calibration(CameraInfo(width=240, height=180))
    with pytest.raises(DecodeError, match='equidistant.*not supported'):
        ros_msgs.camera_info_to_calibration(
            CameraInfo(width=240, height=180, k=k, distortion_model='equidistant', d=[0.1] * 4))
    with pytest.raises(DecodeError, match='past k3'):
        ros_msgs.camera_info_to_calibration(CameraInfo(
            width=240, height=180, k=k, distortion_model='rational_polynomial', d=[0.1] * 8))
    with pytest.raises(DecodeError, match='size 0x180'):
        ros_msgs.camera_info_to_calibration(CameraInfo(width=0, height=180, k=k))


def test_camera_info_focal_length_any_model() -> None:
    k = [199.1, 0.0, 121.3, 0.0, 198.8, 89.6, 0.0, 0.0, 1.0]
    eq = CameraInfo(width=240, height=180, k=k, distortion_model='equidistant', d=[0.1] * 4)
    assert ros_msgs.camera_info_focal(eq) == (199.1, (240, 180))
    with pytest.raises(DecodeError, match=r'k\[0\] = 0: the camera is not calibrated'):
        ros_msgs.camera_info_focal(CameraInfo(width=240, height=180))
    with pytest.raises(DecodeError, match='k.0. = nan'):
        ros_msgs.camera_info_focal(CameraInfo(width=240, height=180, k=[math.nan] + k[1:]))
    with pytest.raises(DecodeError, match='size 240x0'):
        ros_msgs.camera_info_focal(CameraInfo(width=240, height=0, k=k))


def test_static_transform_of_a_camera_looking_down() -> None:
    cfg = OdometryConfig(mount_xyz=(0.5, 0.0, 1.0), mount_rpy=(0.0, math.pi / 2, 0.0))
    R, t = mount_transform(cfg)
    tf = ros_msgs.static_transform(42, 'base_link', 'camera', R, t)
    assert (tf.header.frame_id, tf.child_frame_id) == ('base_link', 'camera')
    assert ros_msgs.stamp_to_ns(tf.header.stamp) == 42
    tr, q = tf.transform.translation, tf.transform.rotation
    assert (tr.x, tr.y, tr.z) == (0.5, 0.0, 1.0)
    # optical x -> -y, y -> -x, z -> -z: half a turn about (1, -1, 0) / sqrt(2)
    got = np.array([q.x, q.y, q.z, q.w])
    want = np.array([1.0, -1.0, 0.0, 0.0]) / math.sqrt(2.0)
    assert np.allclose(got, want, atol=1e-12) or np.allclose(got, -want, atol=1e-12), got
    # looking left (yaw 90 deg): optical x -> x, y -> -z, z -> y, i.e. -90 deg about x
    R, t = mount_transform(OdometryConfig(mount_rpy=(0.0, 0.0, math.pi / 2)))
    q = ros_msgs.static_transform(0, 'base_link', 'camera', R, t).transform.rotation
    h = math.sqrt(0.5)
    np.testing.assert_allclose([q.x, q.y, q.z, q.w], [-h, 0.0, 0.0, h], atol=1e-12)


def test_odometry_message_carries_twist_and_covariances() -> None:
    pose = readout_to_pose(OdometryConfig(focal_length_px=80.0), 5, 8.0, -4.0, 0.3, None,
                           {'h': 1.0, 'v': 0.5, 'r': 0.9})
    cov = np.arange(36, dtype=np.float64).reshape(6, 6)      # row-major order is checked
    tw = Twist(np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0]), cov)
    od = ros_msgs.pose_to_odometry(pose, 'odom', 'base_link', 1e4, tw)
    lin, ang = od.twist.twist.linear, od.twist.twist.angular
    assert (lin.x, lin.y, lin.z, ang.x, ang.y, ang.z) == (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    assert list(od.twist.covariance) == list(range(36))
    assert od.twist.covariance[1] == cov[0, 1] and od.twist.covariance[6] == cov[1, 0]
    pc = np.arange(36, dtype=np.float64).reshape(6, 6) * 0.5
    od = ros_msgs.pose_to_odometry(OdomPose(5, pose.position, pose.quat, pc), 'odom',
                                   'base_link', 1e4, tw)
    assert list(od.pose.covariance) == [0.5 * k for k in range(36)]
    unknown = ros_msgs.pose_to_odometry(pose, 'odom', 'base_link', 1e4)
    assert list(unknown.twist.covariance) == list((np.eye(6) * 1e4).reshape(36))
    assert unknown.twist.twist.linear.x == 0.0


def test_packet_decoder_reset_restarts_the_evt3_time(rng: np.random.Generator) -> None:
    def evt3(t0_us: int) -> EventPacket:
        t = (t0_us + np.arange(50) * 10) * 1000
        ev = EventArray.from_arrays(t, rng.integers(0, 240, 50), rng.integers(0, 180, 50),
                                    np.zeros(50, np.uint8))
        return EventPacket(encoding='evt3', width=240, height=180,
                           events=encode_evt3(ev).tobytes())

    dec = PacketDecoder()
    assert int(ros_msgs.events_from_packet(evt3(9_000_000), dec).t[0]) == 9_000_000_000
    # a camera restart: its time starts again near 0; without a reset that reads as a rollover
    kept = ros_msgs.events_from_packet(evt3(1_000_000), dec)
    assert int(kept.t[0]) == (2**24 + 1_000_000) * 1000
    dec.reset()
    fresh = ros_msgs.events_from_packet(evt3(1_000_000), dec)
    assert int(fresh.t[0]) == 1_000_000_000 and len(fresh) == 50


def test_packet_reader_reads_the_stamp_and_rereads_evt3_from_a_fresh_state(
        rng: np.random.Generator) -> None:
    def evt3(t0_us: int) -> EventPacket:
        t = (t0_us + np.arange(50) * 10) * 1000
        ev = EventArray.from_arrays(t, rng.integers(0, 240, 50), rng.integers(0, 180, 50),
                                    np.zeros(50, np.uint8))
        msg = EventPacket(encoding='evt3', width=240, height=180,
                          events=encode_evt3(ev).tobytes())
        msg.header.stamp = ros_msgs.ns_to_stamp(5 * 10**9 + 7)
        return msg

    reader = ros_msgs.PacketReader()
    header_ns, ev = reader.read(evt3(9_000_000))
    assert header_ns == 5 * 10**9 + 7 and int(ev.t[0]) == 9_000_000_000
    restart = evt3(1_000_000)
    assert int(reader.read(restart)[1].t[0]) == (2**24 + 1_000_000) * 1000   # a rollover
    again = reader.reread(restart)
    assert again is not None and int(again.t[0]) == 1_000_000_000
    assert reader.size(restart) == (240, 180)
    mono = EventPacket(encoding='mono', events=b'')
    assert reader.reread(mono) is None


def test_static_transforms_and_step_messages() -> None:
    odo = OdometryConfig(focal_length_px=80.0)
    msg = ros_msgs.static_transforms(3, static_frames(
        odo, tuple(float(v) for v in np.eye(3).ravel()), base='b', camera='c', imu='i'))
    assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == [('b', 'c'),
                                                                            ('c', 'i')]
    est = Estimate(10**9, 2.0, 0.0, 0.0, 0.0, confidence={'h': 1.0, 'v': 1.0, 'r': 1.0},
                   quality=0.5, state='degraded')
    out = OdometryComposer().compose(10**9, est, odo, with_z=False, lost_variance=1e6,
                                     min_quality=0.05)
    step = Step(10**9, est, odo, out, 0.0)
    readout, pose, odom = ros_msgs.step_messages(step, 'odom', 'base', 'cam', with_tf=False)
    assert list(readout.name) == ['h', 'v', 'r', 'quality', 'state']
    assert pose.header.frame_id == 'odom' and odom.child_frame_id == 'base'
    np.testing.assert_allclose(np.reshape(odom.pose.covariance, (6, 6)), out.pose.covariance)
    msgs = ros_msgs.step_messages(step, 'odom', 'base', 'cam', with_tf=True)
    assert len(msgs) == 4 and msgs[3].transforms[0].child_frame_id == 'base'
    cam = OdometryConfig(focal_length_px=80.0, child_frame='camera')
    odom = ros_msgs.step_messages(Step(10**9, est, cam, out, 0.0), 'odom', 'base', 'cam',
                                  with_tf=False)[2]
    assert odom.child_frame_id == 'cam'
