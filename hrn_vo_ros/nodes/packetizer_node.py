"""``packetizer_node``: event packets in, binary event frames out.

Subscribes ``~/events`` (``event_camera_msgs/EventPacket``, mono or evt3; BEST_EFFORT depth 1000
as the drivers publish, RELIABLE with ``events_reliable``), bins fixed-count packets of events
with :class:`~hrn_vo_ros.core.frames.Packetizer` (a frame may span many messages, a message may
complete many frames) and publishes ``~/frames`` (``sensor_msgs/Image`` mono8 0/255, stamp = the
packet midpoint on the sensor clock, ``frame_id`` from a parameter). Sequence gaps, malformed
packets and rates go to ``/diagnostics``.

Parameters: the fields of ``PacketizerConfig`` and ``PacketizerNodeConfig`` (same names).
"""

from __future__ import annotations

import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from event_camera_msgs.msg import EventPacket
from rclpy.node import Node
from sensor_msgs.msg import Image

from hrn_vo_ros.core.frames import Packetizer, PacketizerConfig
from hrn_vo_ros.core.nodeconfig import PacketizerNodeConfig
from hrn_vo_ros.core.nodestats import NodeStats, packet_problem
from hrn_vo_ros.errors import HrnVoError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.eventpacket import PacketDecoder
from hrn_vo_ros.nodes.common import publish_diagnostics, qos, Rejects, run
from hrn_vo_ros.nodes.params import declare_config


class PacketizerNode(Node):
    """Event packets → binary frames (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('packetizer_node', **kwargs)
        self._algo = declare_config(self, PacketizerConfig, on_change=self._reconfigure)
        self._opts = declare_config(self, PacketizerNodeConfig)
        opts = self._opts.config
        self._packetizer = Packetizer(self._algo.config)
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
        cfg = self._algo.config
        self.get_logger().info(
            f'{cfg.events_per_frame} events per frame, {cfg.sensor_width}x{cfg.sensor_height} '
            f'-> {cfg.width}x{cfg.height}, events '
            f'{"reliable" if opts.events_reliable else "best effort"}')

    def _reconfigure(self, cfg: PacketizerConfig) -> None:
        """A tunable changed: start a new packetizer (pending events are dropped)."""
        self.stats.count('dropped_on_reconfigure', self._packetizer.pending)
        self._packetizer = Packetizer(cfg)
        self.get_logger().info(f'packetizer reconfigured: {cfg}')

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
        try:
            frames = self._packetizer.push(ev)
        except HrnVoError as err:  # checked above; kept as the last line of defence
            self._reject('packetizer', err)
            return
        self.stats.count('events_in', len(ev))
        frame_id = self._opts.config.frame_id
        for f in frames:
            self._pub.publish(ros_msgs.frame_to_image(f.image, f.t_ns, frame_id))
        self.stats.count('frames_out', len(frames))
        self.stats.processing(time.perf_counter() - t0)

    def _on_timer(self) -> None:
        extra: list[tuple[str, object]] = [
            ('frame_rate_hz', f'{self.stats.rate("frames_out"):.1f}'),
            ('pending_events', self._packetizer.pending),
            ('frames_subscribers', self._pub.get_subscription_count())]
        publish_diagnostics(self, self._diag, self.stats, extra)


def main(args: list[str] | None = None) -> int:
    """Console script ``packetizer_node`` (``--ros-args`` are passed through)."""
    return run(PacketizerNode, args)


if __name__ == '__main__':
    sys.exit(main())
