"""``resonator_node``: binary event frames in, odometry out (the HRN as an odometry source).

Subscribes ``~/frames`` (mono8 0/255, keep last ``frames_depth``, drops counted), with
``imu.enabled`` ``~/imu`` (frames wait, bounded, for a gyro sample at or after their time) and,
with ``focal_px`` 0, the first ``~/camera_info`` (fx / D in frame pixels). Publishes, stamped
with the frame time, ``~/readout`` (JointState), ``~/pose``, ``~/odom`` (covariance growing as
quality falls), ``/tf`` (``publish_tf``), ``/tf_static`` (``publish_static_tf``), the map images
and ``/diagnostics`` (WARN while degraded, ERROR while lost or on frames of another size); the
topics, frames and levels in full: docs/demo.md.

The logic is ``core/live.py`` and ``core/odometry/publish.py``; this node translates messages
and parameters (the fields of ``ResonatorConfig``, ``ResonatorNodeConfig`` and, under
``backend.``, ``BackendConfig``); ``loihi_node`` is this node preset to ``backend.name:
spiking``.
"""

from __future__ import annotations

from collections.abc import Iterable
import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image, Imu

from hrn_vo_ros.core.events.stream import Note
from hrn_vo_ros.core.hrn.backends import BackendConfig, ResonatorBackend
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.live import Item, LiveOdometry, LiveSettings, make_resonator
from hrn_vo_ros.core.odometry import publish
from hrn_vo_ros.errors import HrnVoError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.nodeconfig import ResonatorNodeConfig
from hrn_vo_ros.nodes.common import (
    CameraInfoInput,
    NoteLog,
    publish_diagnostics,
    qos,
    worst,
)
from hrn_vo_ros.nodes.outputs import OdometryOutputs
from hrn_vo_ros.nodes.params import declare_config
from hrn_vo_ros.nodes.process import run
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
        self.stats = NodeStats()
        self._live = LiveOdometry(self._make_hrn(cfg), publish.GyroGate(
            cfg.imu.camera_from_imu, max_samples=opts.imu_buffer_samples,
            max_pending=opts.max_pending_frames), (cfg.width, cfg.height),
            tolerance_ns=int(opts.clock_tolerance_s * 1e9), counts=self.stats.counts,
            resize=lambda w, h: self._live.sized(self._algo.config, w, h, self._make_hrn))
        self._note = NoteLog(self, self.stats, lambda: self._opts.config.log_throttle_s)
        self._reject = self._note.reject
        self._out = OdometryOutputs(self, opts.publish_tf)
        self._diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        if opts.publish_static_tf:
            self._publish_static_tf()
        self.create_subscription(Image, '~/frames', self._on_frame, qos(opts.frames_depth))
        if cfg.imu.enabled:
            self.create_subscription(Imu, '~/imu', self._on_imu, qos(
                opts.imu_depth, reliable=opts.imu_reliable, keep_all=opts.imu_reliable))
        self._camera_info = (CameraInfoInput(self, self._on_camera_info)
                             if cfg.focal_px <= 0.0 else None)
        self.create_timer(opts.diagnostics_period_s, self._on_timer)
        self.get_logger().info(self._live.describe(
            cfg, adopt_size=opts.frame_size == 'frames',
            camera_info_topic=None if self._camera_info is None else self._camera_info.topic))

    @property
    def _hrn(self) -> ResonatorBackend:
        """The current resonator (the pipeline's estimator)."""
        return self._live.pipeline.estimator

    def _make_hrn(self, cfg: ResonatorConfig) -> ResonatorBackend:
        """The resonator for ``cfg`` (``core.live.make_resonator``), its warning logged."""
        hrn, why = make_resonator(cfg, self._opts.config.seed, self._backend.config)
        if why is not None:
            self.get_logger().warning(why)
        return hrn

    def _settings(self) -> LiveSettings:
        """The settings ``core/live.py`` reads now (parameters may change between messages):
        the gyro as the resonator runs it (off while the focal length is unknown), a
        camera_info's focal length also for the odometry."""
        opts, cfg = self._opts.config, self._algo.config
        focal, odo = self._live.focal_for(cfg, opts.odometry)
        return LiveSettings(opts.frame_size == 'frames', cfg.imu.enabled and focal > 0.0,
                            'z' in self._hrn.factors, odo, focal, opts.lost_variance,
                            opts.min_quality, opts.imu_timeout_s, cfg.imu.camera_from_imu)

    def _publish_static_tf(self) -> None:
        """base_link → camera (mount) and camera → IMU (``imu.camera_from_imu``) on /tf_static."""
        opts = self._opts.config
        frames, notes = self._live.static_frames(self._settings(), base=opts.base_frame_id,
                                                 camera=opts.camera_frame_id,
                                                 imu=opts.imu_frame_id)
        self._emit(notes)
        self._out.static(frames)

    def _reconfigure(self, cfg: ResonatorConfig) -> None:
        """A tunable changed: a new resonator with the same seed (tracking restarts)."""
        self._live.rebuild(cfg, self._make_hrn)
        self.get_logger().warning('resonator reconfigured: tracking restarts from a new map')

    def _on_camera_info(self, msg: CameraInfo) -> None:
        """The first usable camera_info gives the focal length while ``focal_px`` is unset;
        a resonator that needs it (gyro, sphere correction) is rebuilt with it."""
        if self._live.focal.camera is not None:     # one taken before the subscription closed
            return
        try:
            camera = ros_msgs.camera_info_focal(msg)
        except HrnVoError as err:
            self._reject('camera_info', err)
            return
        if self._camera_info is not None:
            self._camera_info.close()
        self.get_logger().info(self._live.adopt_camera(camera, self._algo.config,
                                                       self._make_hrn))

    def _on_frame(self, msg: Image, info: dict[str, Any]) -> None:
        self.stats.count('frames_in')
        seq = info.get('publication_sequence_number')
        missed = self.stats.sequence(int(seq)) if seq else 0     # frames the queue dropped
        if missed:
            self._emit(self._live.queue_drops(self.stats.seq_gaps, self._opts.config.frames_depth))
        try:
            t_ns, image = ros_msgs.image_to_frame(msg)
        except HrnVoError as err:
            self._reject('decode', err)
            return
        self._emit(self._live.frame(t_ns, image, self._settings()))

    def _on_imu(self, msg: Imu) -> None:
        self.stats.count('imu_in')
        self._emit(self._live.imu_frame(msg.header.frame_id, self._opts.config.imu_frame_id))
        try:
            t_ns, gyro, _ = ros_msgs.imu_to_arrays(msg)
        except (HrnVoError, ValueError, TypeError) as err:
            self._reject('imu', err)
            return
        self._emit(self._live.imu(t_ns, gyro, self._settings()))

    def _emit(self, items: Iterable[Item]) -> None:
        """Count and log the notes, publish each processed frame (before the next is made)."""
        for item in items:
            if isinstance(item, Note):
                self._note(item)
                continue
            t0 = time.perf_counter()
            self._out.step(item, self._opts.config)
            self.stats.processing(item.seconds + time.perf_counter() - t0)
            self._publish_images(item.t_ns)

    def _publish_images(self, t_ns: int) -> bool:
        """The map images, at most ``map_image_rate_hz``; whether they were published."""
        return self._out.images(t_ns, self._hrn, self._opts.config)

    def _on_timer(self) -> None:
        self._emit(self._live.tick(self._settings()))
        if self._live.focal.camera is None and self._camera_info is not None:
            self._camera_info.recheck()
        opts = self._opts.config
        values, states = self._live.diagnostics(
            opts.diagnostics_window_s, (f'{self.stats.rate("estimates_out"):.1f}',
                                        *self._out.subscribers()),
            self._algo.config, opts.odometry, self.resolve_topic_name('~/camera_info'))
        level, message = worst(*states)
        publish_diagnostics(self, self._diag, self.stats, values + self._extra_diagnostics(),
                            level=level, message='running' if level == 'ok' else message,
                            window_s=opts.diagnostics_window_s)

    def _extra_diagnostics(self) -> list[tuple[str, object]]:
        """Hook for presets (loihi_node): more key/values for the diagnostics message."""
        return []


def main(args: list[str] | None = None) -> int:
    """Console script ``resonator_node`` (``--ros-args`` are passed through)."""
    return run(ResonatorNode, args)


if __name__ == '__main__':
    sys.exit(main())
