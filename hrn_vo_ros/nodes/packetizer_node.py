"""``packetizer_node``: event packets in, binary event frames out.

Subscribes ``~/events`` (``event_camera_msgs/EventPacket``, mono or evt3; BEST_EFFORT depth 1000
as the drivers publish, RELIABLE with ``events_reliable``), bins fixed-count packets of events
with `core.events.frames.Packetizer` (a frame may span many messages, a message may
complete many frames) and publishes ``~/frames`` (``sensor_msgs/Image`` mono8 0/255, stamp = the
packet midpoint on the sensor clock, ``frame_id`` from a parameter). Sequence gaps, malformed
packets and rates go to ``/diagnostics``.

With ``rectify`` (``pinhole`` / ``equidistant``) and no ``calib.*`` parameters, the node takes
the calibration from the first ``~/camera_info`` (``sensor_msgs/CameraInfo``, plumb_bob; QoS
best available, so a latched bag topic and a volatile driver topic both work) and holds up to
``camera_info_wait_events`` events until it arrives (older ones are dropped and counted).

Parameters: the fields of ``PacketizerConfig`` and ``PacketizerNodeConfig`` (same names).
"""

from __future__ import annotations

import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from event_camera_msgs.msg import EventPacket
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import Packetizer, PacketizerConfig, with_calibration
from hrn_vo_ros.core.events.sequence import CameraCalibration
from hrn_vo_ros.errors import HrnVoError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.eventpacket import PacketDecoder
from hrn_vo_ros.io.nodeconfig import PacketizerNodeConfig
from hrn_vo_ros.nodes.common import publish_diagnostics, qos, Rejects, run
from hrn_vo_ros.nodes.params import declare_config
from hrn_vo_ros.nodes.stats import NodeStats, packet_problem


class PacketizerNode(Node):
    """Event packets → binary frames (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('packetizer_node', **kwargs)
        self._algo = declare_config(self, PacketizerConfig, on_change=self._reconfigure)
        self._opts = declare_config(self, PacketizerNodeConfig)
        opts = self._opts.config
        self._calib: CameraCalibration | None = None
        self._waiting: list[EventArray] = []
        self._waiting_n = 0
        self._packetizer: Packetizer | None = None
        cfg = self._algo.config
        if self._needs_camera_info(cfg):
            latched_or_not = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_AVAILABLE,
                                        durability=DurabilityPolicy.BEST_AVAILABLE)
            self.create_subscription(CameraInfo, '~/camera_info', self._on_camera_info,
                                     latched_or_not)
        else:
            self._packetizer = Packetizer(cfg)
        self._decoder = PacketDecoder()
        self._last_t: int | None = None
        self.stats = NodeStats()
        self._reject = Rejects(self, self.stats, lambda: self._opts.config.log_throttle_s)
        self._pub = self.create_publisher(Image, '~/frames', qos(opts.frames_depth))
        self._diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_subscription(EventPacket, '~/events', self._on_events,
                                 qos(opts.events_depth, reliable=opts.events_reliable,
                                     keep_all=opts.events_keep_all))
        self.create_timer(opts.diagnostics_period_s, self._on_timer)
        waiting = ('' if self._packetizer is not None else
                   ' (no calib.* parameters: events are held until a camera_info arrives on '
                   f'{self.resolve_topic_name("~/camera_info")})')
        self.get_logger().info(
            f'{cfg.events_per_frame} events per frame, {cfg.sensor_width}x{cfg.sensor_height} '
            f'-> {cfg.width}x{cfg.height}, rectify {cfg.rectify}{waiting}, events '
            f'{"reliable" if opts.events_reliable else "best effort"}')

    @staticmethod
    def _needs_camera_info(cfg: PacketizerConfig) -> bool:
        return cfg.rectify != 'none' and not cfg.calib.known

    def _reconfigure(self, cfg: PacketizerConfig) -> None:
        """A tunable changed: start a new packetizer (pending events are dropped)."""
        if self._packetizer is None:     # still waiting for camera_info: applied when it comes
            return
        self.stats.count('dropped_on_reconfigure', self._packetizer.pending)
        if self._calib is not None:
            cfg = with_calibration(cfg, self._calib)
        self._packetizer = Packetizer(cfg)
        self.get_logger().info(f'packetizer reconfigured: {cfg}')

    def _on_camera_info(self, msg: CameraInfo) -> None:
        if self._packetizer is not None:
            return
        try:
            calib = ros_msgs.camera_info_to_calibration(msg)
            packetizer = Packetizer(with_calibration(self._algo.config, calib))
        except HrnVoError as err:
            self._reject('camera_info', err)
            return
        self._calib, self._packetizer = calib, packetizer
        self.get_logger().info(
            f'camera_info: fx {calib.fx:.1f} fy {calib.fy:.1f} cx {calib.cx:.1f} '
            f'cy {calib.cy:.1f} dist {list(calib.dist)}; rectifying, {self._waiting_n} held '
            'events go first')
        held, self._waiting, self._waiting_n = self._waiting, [], 0
        for ev in held:
            self._push(ev)

    def _hold(self, ev: EventArray) -> None:
        """Keep events until camera_info arrives, dropping the oldest beyond the limit."""
        self._waiting.append(ev)
        self._waiting_n += len(ev)
        limit = self._opts.config.camera_info_wait_events
        while self._waiting_n > limit and self._waiting:
            old = self._waiting.pop(0)
            self._waiting_n -= len(old)
            self.stats.count('dropped_waiting_for_camera_info', len(old))
            dropped = self.stats.counts['dropped_waiting_for_camera_info']
            self.get_logger().warning(
                f'no camera_info yet ({dropped} events dropped so far): publish it on '
                '~/camera_info, set the calib.* parameters or set rectify to none',
                throttle_duration_sec=self._opts.config.log_throttle_s)

    def _on_events(self, msg: EventPacket) -> None:
        t0 = time.perf_counter()
        self.stats.count('packets_in')
        missed = self.stats.sequence(int(msg.seq))
        if missed:
            self.get_logger().warning(f'{missed} event packet(s) lost before seq {msg.seq} '
                                      f'({self.stats.seq_gaps} so far)',
                                      throttle_duration_sec=self._opts.config.log_throttle_s)
        try:
            ev = ros_msgs.events_from_packet(msg, self._decoder)
        except HrnVoError as err:
            self._reject('decode', err)
            return
        problem = packet_problem(ev, self._algo.config, self._last_t)
        if problem is not None:
            self._reject(problem, f'seq {msg.seq}, {len(ev)} events')
            return
        self._last_t = int(ev.t[-1])
        self.stats.count('events_in', len(ev))
        if self._packetizer is None:
            self._hold(ev)
        else:
            self._push(ev)
        self.stats.processing(time.perf_counter() - t0)

    def _push(self, ev: EventArray) -> None:
        assert self._packetizer is not None
        try:
            frames = self._packetizer.push(ev)
        except HrnVoError as err:  # checked above; kept as the last line of defence
            self._reject('packetizer', err)
            return
        frame_id = self._opts.config.frame_id
        for f in frames:
            self._pub.publish(ros_msgs.frame_to_image(f.image, f.t_ns, frame_id))
        self.stats.count('frames_out', len(frames))

    def _on_timer(self) -> None:
        extra: list[tuple[str, object]] = [
            ('frame_rate_hz', f'{self.stats.rate("frames_out"):.1f}'),
            ('pending_events', 0 if self._packetizer is None else self._packetizer.pending),
            ('rectify', self._algo.config.rectify),
            ('waiting_for_camera_info', self._packetizer is None),
            ('events_held', self._waiting_n),
            ('events_outside_frame', 0 if self._packetizer is None
             else self._packetizer.outside),
            ('frames_subscribers', self._pub.get_subscription_count())]
        publish_diagnostics(self, self._diag, self.stats, extra)


def main(args: list[str] | None = None) -> int:
    """Console script ``packetizer_node`` (``--ros-args`` are passed through)."""
    return run(PacketizerNode, args)


if __name__ == '__main__':
    sys.exit(main())
