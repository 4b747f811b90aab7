"""``resonator_node``: binary event frames in, odometry out (the HRN as an odometry source).

Subscribes ``~/frames`` (``sensor_msgs/Image`` mono8 0/255, RELIABLE) and, when the resonator's
``imu.enabled`` is true, ``~/imu`` (``sensor_msgs/Imu``, best effort depth 1000; frames wait,
bounded, until a gyro sample at or after their time arrived). Publishes, stamped with the frame
time:

* ``~/readout`` — raw h, v, r [, z], quality and state code as ``sensor_msgs/JointState``
  (io/ros_msgs.py);
* ``~/pose`` (PoseStamped) and ``~/odom`` (nav_msgs/Odometry with covariance) in
  ``odom_frame_id``; ``/tf`` when ``publish_tf``;
* ``~/map_image`` and ``~/readout_image`` (mono8, at most ``map_image_rate_hz``);
* ``/tf_static`` (``publish_static_tf``): ``base_frame_id`` → ``camera_frame_id`` from
  ``odometry.mount_*`` and, with ``imu_frame_id``, ``camera_frame_id`` → ``imu_frame_id`` from
  ``imu.camera_from_imu``;
* ``/diagnostics``: frame rate, processing time, tracking confidence, quality and state,
  rejected messages. WARN while degraded (or a message was rejected within
  ``diagnostics_window_s``), ERROR while lost, OK again once tracking. ERROR while frames of
  another size than ``width`` x ``height`` arrive (all dropped), the message naming the two
  values to set (the resonator's width/height or the packetizer's downsample).

Stamps: every output carries its frame's stamp (the header clock of the event packets, see
``core/clock.py``); IMU samples are taken in their own header clock (ROS time for a live
driver), the same clock. A frame or IMU stamp going back by more than ``clock_tolerance_s``
(a restart, a looped bag) restarts that stream's time state (counted, logged, throttled).

Tracking state (``Estimate.quality``, ``Estimate.state``): the pose and twist covariances are
divided by ``max(quality, min_quality)²`` (they grow as quality falls) and are
``lost_variance`` (1e6) on the diagonal while lost, so a filter such as robot_localization
effectively ignores those measurements (its Kalman gain is about 0) and coasts on its model
and other sensors. The twist is the finite difference of consecutive poses.

Parameters: the fields of ``ResonatorConfig`` and ``ResonatorNodeConfig`` (same names), and
``backend.name`` (``float`` or ``spiking``) with ``backend.spiking.*`` (``BackendConfig``).
``loihi_node`` is this node preset to the spiking backend.

Per frame the node runs the odometry pipeline (``core.pipeline.OdometryPipeline.step``: gyro
increment, then the resonator), the same step ``hrn-vo run`` takes, so a graph fed a dataset
reproduces ``hrn-vo run``'s estimates.
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace
import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, Imu, JointState
from tf2_msgs.msg import TFMessage

from hrn_vo_ros.core.clock import StampChecker, Verdict
from hrn_vo_ros.core.hrn.backends import BackendConfig, make_backend, ResonatorBackend
from hrn_vo_ros.core.hrn.config import ResonatorConfig, without_unset_sphere
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.core.odometry.odometry import (
    mount_transform,
    OdometryConfig,
    OdomPose,
    readout_to_pose,
    Twist,
    twist_between,
)
from hrn_vo_ros.core.pipeline import OdometryPipeline
from hrn_vo_ros.errors import HrnVoError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.nodeconfig import ResonatorNodeConfig
from hrn_vo_ros.nodes.common import publish_diagnostics, qos, Rejects, run, worst
from hrn_vo_ros.nodes.params import declare_config
from hrn_vo_ros.nodes.stats import NodeStats


class ResonatorNode(Node):
    """Event frames → HRN → pose, odometry, raw readouts (see the module docstring)."""

    def __init__(self, node_name: str = 'resonator_node', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._algo = declare_config(self, ResonatorConfig, on_change=self._reconfigure)
        self._opts = declare_config(self, ResonatorNodeConfig)
        self._backend = declare_config(self, BackendConfig, prefix='backend.',
                                       on_change=lambda _: self._reconfigure(self._algo.config))
        opts, cfg = self._opts.config, self._algo.config
        self._gyro = GyroIntegrator(np.reshape(cfg.imu.camera_from_imu, (3, 3)),
                                    max_samples=opts.imu_buffer_samples)
        self._pipeline = OdometryPipeline(self._make_hrn(cfg), gyro=self._gyro, record=False)
        self.stats = NodeStats()
        self._reject = Rejects(self, self.stats, lambda: self._opts.config.log_throttle_s)
        tol = int(opts.clock_tolerance_s * 1e9)
        self._frame_clock = StampChecker(tol)
        self._imu_clock = StampChecker(tol, strict=True)
        self._prev_pose: OdomPose | None = None
        self._quality, self._state = 1.0, 'tracking'
        self._last_reset_wall = -1e18
        self._size_mismatch: tuple[float, str] | None = None   # (wall time, what to set)
        self._odo_key: tuple[OdometryConfig, float] | None = None
        self._odo = opts.odometry
        self._pending: deque[tuple[int, np.ndarray, float]] = deque()
        self._last_image_wall = self._last_imu_wall = 0.0
        self._confidence: dict[str, float] = {}
        self._pub_readout = self.create_publisher(JointState, '~/readout', qos(1000))
        self._pub_pose = self.create_publisher(PoseStamped, '~/pose', qos(1000))
        self._pub_odom = self.create_publisher(Odometry, '~/odom', qos(1000))
        self._pub_map = self.create_publisher(Image, '~/map_image', 2)
        self._pub_readout_img = self.create_publisher(Image, '~/readout_image', 2)
        self._pub_tf = self.create_publisher(TFMessage, '/tf', 100) if opts.publish_tf else None
        self._diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        if opts.publish_static_tf:
            self._publish_static_tf()
        self.create_subscription(Image, '~/frames', self._on_frame, qos(opts.frames_depth))
        if cfg.imu.enabled:
            self.create_subscription(Imu, '~/imu', self._on_imu, qos(
                opts.imu_depth, reliable=opts.imu_reliable, keep_all=opts.imu_reliable))
        self.create_timer(opts.diagnostics_period_s, self._on_timer)
        self.get_logger().info(f'{cfg.width}x{cfg.height} frames, factors '
                               f'{"/".join(self._hrn.factors)}, IMU {cfg.imu.enabled}')

    @property
    def _hrn(self) -> ResonatorBackend:
        """The current resonator (the pipeline's estimator)."""
        return self._pipeline.estimator

    def _make_hrn(self, cfg: ResonatorConfig) -> ResonatorBackend:
        """The resonator for ``cfg`` (seeded; without a focal length, without the sphere
        correction: the node has no calibration, a live camera should still give odometry)."""
        cfg, why = without_unset_sphere(cfg)
        if why is not None:
            self.get_logger().warning(why)
        return make_backend(cfg, rng=np.random.default_rng(self._opts.config.seed),
                            backend=self._backend.config)

    @property
    def _odometry(self) -> OdometryConfig:
        """``odometry.*``; the resonator's ``focal_px`` (when set) is the one focal length."""
        odo, focal = self._opts.config.odometry, self._algo.config.focal_px
        if self._odo_key == (odo, focal):
            return self._odo
        self._odo_key = (odo, focal)
        if focal > 0.0 and abs(odo.focal_length_px - focal) > 1e-9 * focal:
            self.get_logger().warning(
                f'focal_px {focal:g} and odometry.focal_length_px {odo.focal_length_px:g} '
                'differ: the odometry uses focal_px (one focal length for every stage)')
            odo = replace(odo, focal_length_px=focal)
        self._odo = odo
        return odo

    def _publish_static_tf(self) -> None:
        """base_link → camera (mount) and camera → IMU (``imu.camera_from_imu``) on /tf_static."""
        opts = self._opts.config
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._pub_static = self.create_publisher(TFMessage, '/tf_static', latched)
        now = self.get_clock().now().nanoseconds
        R, t = mount_transform(self._odometry)
        tfs = [ros_msgs.static_transform(now, opts.base_frame_id, opts.camera_frame_id, R, t)]
        if opts.imu_frame_id:
            R_ci = np.reshape(self._algo.config.imu.camera_from_imu, (3, 3))
            tfs.append(ros_msgs.static_transform(now, opts.camera_frame_id, opts.imu_frame_id,
                                                 R_ci, np.zeros(3)))
        self._pub_static.publish(TFMessage(transforms=tfs))

    def _restart_time(self, what: str) -> None:
        """A stream's stamps went back (restart, looped bag): clear the time state."""
        self.stats.count(f'clock_resets_{what}')
        self._last_reset_wall = time.monotonic()
        self._prev_pose = None
        self._drain(force=True)
        self._gyro = GyroIntegrator(np.reshape(self._algo.config.imu.camera_from_imu, (3, 3)),
                                    max_samples=self._opts.config.imu_buffer_samples)
        self._pipeline.gyro = self._gyro
        self.get_logger().warning(f'{what} stamps went back by more than clock_tolerance_s: '
                                  'time state restarted (a driver restart or a looped bag)',
                                  throttle_duration_sec=self._opts.config.log_throttle_s)

    def _reconfigure(self, cfg: ResonatorConfig) -> None:
        """A tunable changed: a new resonator with the same seed (tracking restarts)."""
        self._pipeline.estimator = self._make_hrn(cfg)
        self._prev_pose = None
        self.get_logger().warning('resonator reconfigured: tracking restarts from a new map')

    def _on_frame(self, msg: Image) -> None:
        self.stats.count('frames_in')
        try:
            t_ns, image = ros_msgs.image_to_frame(msg)
        except HrnVoError as err:
            self._reject('decode', err)
            return
        cfg = self._algo.config
        if image.shape != (cfg.height, cfg.width):
            self._on_size_mismatch(image.shape[1], image.shape[0])
            return
        verdict = self._frame_clock.observe(t_ns)
        if verdict is Verdict.BACKWARDS:
            self._reject('time_backwards', f'frame at {t_ns} ns is older than the previous')
            return
        if verdict is Verdict.RESET:
            self._restart_time('frames')
        if not cfg.imu.enabled:
            self._process(t_ns, image, imu=False)
            return
        self._pending.append((t_ns, image, time.monotonic()))
        self._drain(force=False)

    def _on_size_mismatch(self, w: int, h: int) -> None:
        """Frames of another size than ``width`` x ``height``: every one is dropped (ERROR).

        The usual cause is ``sensor_size: messages`` (config/live.yaml): the packetizer's frame
        is ceil(sensor / downsample), which for another camera is not the resonator's fixed
        size. The log and the diagnostics name the two values to set.
        """
        cfg = self._algo.config
        self._size_mismatch = (time.monotonic(), f'frames are {w}x{h}, width/height are '
                               f'{cfg.width}x{cfg.height}: set the resonator width: {w} and '
                               f'height: {h}, or the packetizer downsample so that its '
                               f'frame is {cfg.width}x{cfg.height} (downsample = sensor '
                               f'width / {cfg.width})')
        self._reject('size', self._size_mismatch[1])

    def _on_imu(self, msg: Imu) -> None:
        self.stats.count('imu_in')
        opts = self._opts.config
        if opts.imu_frame_id and msg.header.frame_id != opts.imu_frame_id:
            self.stats.count('imu_frame_mismatch')
            self.get_logger().warning(
                f'IMU message in frame {msg.header.frame_id!r}, imu_frame_id is '
                f'{opts.imu_frame_id!r}: imu.camera_from_imu must rotate that frame',
                throttle_duration_sec=opts.log_throttle_s)
        try:
            t_ns, gyro, _ = ros_msgs.imu_to_arrays(msg)
            verdict = self._imu_clock.observe(t_ns)
            if verdict is Verdict.BACKWARDS:
                self._reject('imu_time', f'IMU sample at {t_ns} ns does not increase')
                return
            if verdict is Verdict.RESET:
                self._restart_time('imu')
            self._gyro.add(t_ns, gyro)
        except (HrnVoError, ValueError, TypeError) as err:
            self._reject('imu', err)
            return
        self._last_imu_wall = time.monotonic()
        self._drain(force=False)

    def _drain(self, *, force: bool) -> None:
        """Process waiting frames whose gyro increment is final (or all, when forced)."""
        limit = self._opts.config.max_pending_frames
        while self._pending and (force or len(self._pending) > limit
                                 or self._gyro.covers(self._pending[0][0])):
            t_ns, image, _ = self._pending.popleft()
            self._process(t_ns, image, imu=True)
            self._gyro.trim(t_ns)

    def _process(self, t_ns: int, image: np.ndarray, *, imu: bool) -> None:
        """One frame through the pipeline (with the gyro increment when ``imu``), published."""
        t0 = time.perf_counter()
        try:
            est = self._pipeline.step(image, t_ns, use_gyro=imu)
        except HrnVoError as err:
            self._reject('tracking', err)
            return
        opts = self._opts.config
        values = {'h': est.h, 'v': est.v, 'r': est.r}
        if 'z' in self._hrn.factors:
            values['z'] = est.z
        z = est.z if 'z' in values else None
        self._confidence = est.confidence
        odo = self._odometry
        pose = readout_to_pose(odo, t_ns, est.h, est.v, est.r, z, est.confidence)
        twist = None if self._prev_pose is None else twist_between(
            self._prev_pose, pose, odo.unobserved_variance)
        self._prev_pose = pose
        pose, twist = self._honest(est, pose, twist)
        child = opts.base_frame_id if odo.child_frame == 'base_link' else opts.camera_frame_id
        self._pub_readout.publish(ros_msgs.readout_to_joint_state(
            t_ns, values, est.confidence, quality=est.quality, state=est.state))
        self._pub_pose.publish(ros_msgs.pose_to_pose_stamped(pose, opts.odom_frame_id))
        self._pub_odom.publish(ros_msgs.pose_to_odometry(
            pose, opts.odom_frame_id, child, odo.unobserved_variance, twist))
        if self._pub_tf is not None:
            self._pub_tf.publish(ros_msgs.pose_to_tf(pose, opts.odom_frame_id, child))
        self.stats.count('estimates_out')
        self.stats.count('invalid_frames', 0 if est.valid else 1)
        self.stats.processing(time.perf_counter() - t0)
        self._publish_images(t_ns)

    def _honest(self, est: Estimate, pose: OdomPose, twist: Twist | None
                ) -> tuple[OdomPose, Twist | None]:
        """Covariances that grow as quality falls, ``lost_variance`` while lost."""
        opts = self._opts.config
        self._quality, self._state = float(est.quality), str(est.state)
        if self._state == 'lost':
            cov = np.eye(6) * opts.lost_variance
            pose = OdomPose(pose.t_ns, pose.position, pose.quat, cov)
            return pose, None if twist is None else Twist(twist.linear, twist.angular, cov)
        q = self._quality if np.isfinite(self._quality) else 0.0
        k = 1.0 / max(min(q, 1.0), opts.min_quality) ** 2
        if k == 1.0:
            return pose, twist
        pose = OdomPose(pose.t_ns, pose.position, pose.quat, pose.covariance * k)
        if twist is not None:
            twist = Twist(twist.linear, twist.angular, twist.covariance * k)
        return pose, twist

    def _publish_images(self, t_ns: int) -> None:
        rate = self._opts.config.map_image_rate_hz
        now = time.monotonic()
        if rate <= 0.0 or now - self._last_image_wall < 1.0 / rate:
            return
        self._last_image_wall = now
        frame = self._opts.config.camera_frame_id
        self._pub_map.publish(ros_msgs.float_image_to_mono8(self._hrn.map_image(), t_ns, frame))
        self._pub_readout_img.publish(
            ros_msgs.float_image_to_mono8(self._hrn.egocentric_map_image(), t_ns, frame))

    def _on_timer(self) -> None:
        now, timeout = time.monotonic(), self._opts.config.imu_timeout_s
        if self._pending and min(now - self._pending[0][2], now - self._last_imu_wall) > timeout:
            self._drain(force=True)  # the IMU stopped (end of a bag): do not hold frames
        extra: list[tuple[str, object]] = [
            ('frame_rate_hz', f'{self.stats.rate("estimates_out"):.1f}'),
            ('pending_frames', len(self._pending)), ('gyro_samples', len(self._gyro)),
            ('output_subscribers', min(p.get_subscription_count() for p in (
                self._pub_readout, self._pub_pose, self._pub_odom))),
            ('odom_subscribers', self._pub_odom.get_subscription_count()),
            ('imu_rejected_frames', self._hrn.rejected_frames)]
        extra += [(f'confidence_{k}', f'{v:.3f}') for k, v in sorted(self._confidence.items())]
        extra += [('quality', f'{self._quality:.3f}'), ('tracking_state', self._state),
                  ('clock_resets', self._frame_clock.resets + self._imu_clock.resets)]
        extra += self._extra_diagnostics()
        opts = self._opts.config
        states = []
        if self._size_mismatch is not None and \
                time.monotonic() - self._size_mismatch[0] <= opts.diagnostics_window_s:
            states.append(('error', f'every frame dropped: {self._size_mismatch[1]}'))
        states.append(('error' if self._state == 'lost' else 'warn' if self._state == 'degraded'
                       else 'ok', f'tracking {self._state} (quality {self._quality:.2f})'))
        if time.monotonic() - self._last_reset_wall <= opts.diagnostics_window_s:
            states.append(('warn', 'stamps went back: time state restarted'))
        level, message = worst(*states)
        if level == 'ok':
            message = 'running'
        publish_diagnostics(self, self._diag, self.stats, extra, level=level, message=message,
                            window_s=opts.diagnostics_window_s)

    def _extra_diagnostics(self) -> list[tuple[str, object]]:
        """Hook for presets (loihi_node): more key/values for the diagnostics message."""
        return []


def main(args: list[str] | None = None) -> int:
    """Console script ``resonator_node`` (``--ros-args`` are passed through)."""
    return run(ResonatorNode, args)


if __name__ == '__main__':
    sys.exit(main())
