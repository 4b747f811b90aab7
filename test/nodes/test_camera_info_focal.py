"""resonator_node without focal_px, over DDS: the focal length from the camera's camera_info.

Before the camera_info the gyro is off (frames go without waiting for IMU samples, WARN naming
what to set); after it the gyro is on and the odometry turns h into pan through fx / D.
"""

from __future__ import annotations

from collections.abc import Callable
import math

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from hrn_synth import event_frame, random_scene
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers import spin_until
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState

from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.nodes.common import qos
from hrn_vo_ros.nodes.resonator_node import ResonatorNode

pytestmark = pytest.mark.ros
T0, DT = 1_000_000_000, 10_000_000


def test_focal_length_from_camera_info_turns_the_gyro_on_and_scales_the_odometry() -> None:
    rclpy.init()
    node = ResonatorNode(parameter_overrides=[
        Parameter('diagnostics_period_s', value=0.1), Parameter('imu.enabled', value=True),
        Parameter('frame_size', value='frames'), Parameter('imu_timeout_s', value=60.0),
        Parameter('map_image_rate_hz', value=0.0), Parameter('diagnostics_window_s', value=0.3),
        Parameter('odometry.child_frame', value='camera')])        # the optical frame
    probe = Node('focal_probe')
    poses: list[PoseStamped] = []
    readouts: list[JointState] = []
    diags: list[DiagnosticArray] = []
    frames = probe.create_publisher(Image, '/resonator_node/frames', qos(100))
    imu = probe.create_publisher(Imu, '/resonator_node/imu', qos(100))
    info = probe.create_publisher(CameraInfo, '/resonator_node/camera_info', QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))                 # latched, as drivers do
    probe.create_subscription(PoseStamped, '/resonator_node/pose', poses.append, qos(1000))
    probe.create_subscription(JointState, '/resonator_node/readout', readouts.append, qos(1000))
    probe.create_subscription(DiagnosticArray, '/diagnostics',
                              lambda m: diags.append(m) if m.status[0].name.startswith(
                                  'resonator_node') else None, 100)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    ex.add_node(probe)

    def wait(cond: Callable[[], bool], timeout: float = 15.0) -> bool:
        return spin_until(ex, cond, timeout)

    def last() -> dict[str, str]:
        return ros_msgs.diagnostic_values(diags[-1]) if diags else {}

    rng = np.random.default_rng(3)
    scene = random_scene(rng)

    def send(i: int) -> None:                   # panning right, 0.5 px per frame
        frames.publish(ros_msgs.frame_to_image(
            event_frame(scene, (0.5 * i, 0.0, 0.0, 0.0), rng), T0 + i * DT, 'cam'))

    try:
        assert wait(lambda: frames.get_subscription_count() > 0
                    and imu.get_subscription_count() > 0)
        for i in range(4):                      # no camera_info yet: no IMU wait, no reject
            send(i)
        assert wait(lambda: len(poses) == 4)
        assert wait(lambda: last().get('focal_source') == 'odometry.focal_length_px')
        status = diags[-1].status[0]
        assert status.level == b'\x01' and 'imu.enabled needs focal_px' in status.message
        assert '/resonator_node/camera_info' in status.message
        assert last()['focal_px'] == '79.6' and 'bad_tracking' not in last()

        info.publish(CameraInfo(width=346, height=260))      # uncalibrated: refused, counted
        assert wait(lambda: last().get('bad_camera_info') == '1')
        assert last()['focal_source'] == 'odometry.focal_length_px'
        # a DAVIS346 binned into 96x72 (auto factor 260 / 72; the width alone says 346 / 96)
        info.publish(CameraInfo(width=346, height=260, k=[260.0, 0, 173, 0, 260.0, 130, 0, 0, 1]))
        assert wait(lambda: last().get('focal_source') == 'camera_info')
        assert last()['focal_px'] == '72'
        assert wait(lambda: diags[-1].status[0].level == b'\x00')   # the reject's window over
        for i in range(4, 16):
            send(i)
        ex.spin_once(timeout_sec=0.3)
        assert len(poses) == 4                  # the gyro is on: the frames wait for it
        for k in range(0, 17):                  # a still gyro, 100 Hz
            m = Imu()
            m.header.stamp = ros_msgs.ns_to_stamp(T0 + 35 * DT // 10 + k * DT)
            imu.publish(m)
        assert wait(lambda: len(poses) == 16 and len(readouts) == 16)
        assert readouts[-1].header.stamp == poses[-1].header.stamp
        h = readouts[-1].position[0]
        q = poses[-1].pose.orientation
        R = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
        pan = math.atan2(R[0, 2], R[2, 2])      # R = Ry(pan) Rx(tilt) Rz(roll)
        assert abs(h) > 0.05
        assert pan == pytest.approx(math.atan(h / 72.0), rel=1e-6, abs=1e-9)
        assert pan != pytest.approx(math.atan(h / 79.6), rel=1e-3)
        assert pan != pytest.approx(math.atan(h / (260.0 * 96 / 346)), rel=1e-4)
    finally:
        node.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown()
