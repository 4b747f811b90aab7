"""``resonator_node``: binary event frames in, odometry out (the HRN as an odometry source).

Subscribes ``~/frames`` (``sensor_msgs/Image`` mono8 0/255, RELIABLE) and, when the resonator's
``imu.enabled`` is true, ``~/imu`` (``sensor_msgs/Imu``, best effort depth 1000; frames wait,
bounded, until a gyro sample at or after their time arrived). Publishes, stamped with the frame
time:

* ``~/readout`` — raw h, v, r [, z] as ``sensor_msgs/JointState`` (io/ros_msgs.py);
* ``~/pose`` (PoseStamped) and ``~/odom`` (nav_msgs/Odometry with covariance) in
  ``odom_frame_id``; ``/tf`` when ``publish_tf``;
* ``~/map_image`` and ``~/readout_image`` (mono8, at most ``map_image_rate_hz``);
* ``/diagnostics``: frame rate, processing time, tracking confidence, rejected messages.

Parameters: the fields of ``ResonatorConfig`` and ``ResonatorNodeConfig`` (same names), and
``backend.name`` (``float`` or ``spiking``) with ``backend.spiking.*`` (``BackendConfig``).
``loihi_node`` is this node preset to the spiking backend.

Per frame the node runs the odometry pipeline (``core.pipeline.OdometryPipeline.step``: gyro
increment, then the resonator), the same step ``hrn-vo run`` takes, so a graph fed a dataset
reproduces ``hrn-vo run``'s estimates.
"""

from __future__ import annotations

from collections import deque
import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import Image, Imu, JointState
from tf2_msgs.msg import TFMessage

from hrn_vo_ros.core.hrn.backends import BackendConfig, make_backend, ResonatorBackend
from hrn_vo_ros.core.hrn.config import ResonatorConfig, without_unset_sphere
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.core.odometry.odometry import readout_to_pose
from hrn_vo_ros.core.pipeline import OdometryPipeline
from hrn_vo_ros.errors import HrnVoError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.nodeconfig import ResonatorNodeConfig
from hrn_vo_ros.nodes.common import publish_diagnostics, qos, Rejects, run
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
        self._last_t: int | None = None
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

    def _reconfigure(self, cfg: ResonatorConfig) -> None:
        """A tunable changed: a new resonator with the same seed (tracking restarts)."""
        self._pipeline.estimator = self._make_hrn(cfg)
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
            self._reject('size', f'frame of {image.shape[::-1]} pixels, expected '
                         f'{cfg.width}x{cfg.height}: match packetizer and resonator sizes')
            return
        if self._last_t is not None and t_ns < self._last_t:
            self._reject('time_backwards', f'frame at {t_ns} ns after one at {self._last_t} ns')
            return
        self._last_t = t_ns
        if not cfg.imu.enabled:
            self._process(t_ns, image, imu=False)
            return
        self._pending.append((t_ns, image, time.monotonic()))
        self._drain(force=False)

    def _on_imu(self, msg: Imu) -> None:
        self.stats.count('imu_in')
        try:
            t_ns, gyro, _ = ros_msgs.imu_to_arrays(msg)
            self._gyro.add(t_ns, gyro)
        except HrnVoError as err:
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
        pose = readout_to_pose(opts.odometry, t_ns, est.h, est.v, est.r, z, est.confidence)
        child = opts.base_frame_id if opts.odometry.child_frame == 'base_link' \
            else opts.camera_frame_id
        self._pub_readout.publish(ros_msgs.readout_to_joint_state(t_ns, values, est.confidence))
        self._pub_pose.publish(ros_msgs.pose_to_pose_stamped(pose, opts.odom_frame_id))
        self._pub_odom.publish(ros_msgs.pose_to_odometry(
            pose, opts.odom_frame_id, child, opts.odometry.unobserved_variance))
        if self._pub_tf is not None:
            self._pub_tf.publish(ros_msgs.pose_to_tf(pose, opts.odom_frame_id, child))
        self.stats.count('estimates_out')
        self.stats.count('invalid_frames', 0 if est.valid else 1)
        self.stats.processing(time.perf_counter() - t0)
        self._publish_images(t_ns)

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
        extra += self._extra_diagnostics()
        publish_diagnostics(self, self._diag, self.stats, extra)

    def _extra_diagnostics(self) -> list[tuple[str, object]]:
        """Hook for presets (loihi_node): more key/values for the diagnostics message."""
        return []


def main(args: list[str] | None = None) -> int:
    """Console script ``resonator_node`` (``--ros-args`` are passed through)."""
    return run(ResonatorNode, args)


if __name__ == '__main__':
    sys.exit(main())
