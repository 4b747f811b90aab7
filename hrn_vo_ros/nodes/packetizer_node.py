"""``packetizer_node``: event packets in, binary event frames out.

Subscribes ``~/events`` (``event_camera_msgs/EventPacket``, mono or evt3; BEST_EFFORT depth 1000
as the drivers publish, RELIABLE with ``events_reliable``), bins fixed-count (or time-capped,
refilled) packets of events with `core.events.frames.Packetizer` (a frame may span many
messages, a message may complete many frames) and publishes ``~/frames``
(``sensor_msgs/Image`` mono8 0/255, ``frame_id`` from a parameter). Sequence gaps, malformed
packets and rates go to ``/diagnostics``.

Clocks (``core/clock.py``, docs/demo.md "Clocks"): a frame's stamp is its packet midpoint mapped
from the sensor clock to the **header clock** of the event packets (ROS time for a live driver;
the sensor time itself for a converted bag, where header = time_base) by a running-minimum
offset that follows drift. A driver restart, a looped bag or one far-future packet resets the
mapping (the partial frame of the old clock is dropped, ``clock_resets_*`` counted, a throttled
warning logged) and the decoder's stream state (evt3 time bits and rollovers; the packet is
decoded again), and the stream goes on; ``clock.stamps: sensor`` keeps the sensor clock.

Sensor size: ``sensor_size: config`` uses ``sensor_width``/``sensor_height`` and warns
(throttled) when the packets say otherwise; ``sensor_size: messages`` takes the EventPacket's
width/height (the first packet with a size; a later change restarts the packetizer).

With ``rectify`` (``pinhole`` / ``equidistant``) and no ``calib.*`` parameters, the node takes
the calibration from the first ``~/camera_info`` (``sensor_msgs/CameraInfo``, plumb_bob; QoS
best available, re-resolved whenever the set of camera_info publishers changes while waiting,
so a latched bag topic and a volatile driver topic both work, whichever starts first) and holds
up to ``camera_info_wait_events`` events until it arrives (older ones are dropped and counted).
Diagnostics are WARN while it waits or holds events, OK once it rectifies.

Parameters: the fields of ``PacketizerConfig`` and ``PacketizerNodeConfig`` (same names).
The stream logic (sensor size, held events, clock resets) is ``core/events/stream.py``.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from event_camera_msgs.msg import EventPacket
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image

from hrn_vo_ros.core.events.packet_config import PacketizerConfig
from hrn_vo_ros.core.events.stream import DECODE_ERRORS, PacketStream, StreamOutput
from hrn_vo_ros.errors import HrnVoError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.nodeconfig import PacketizerNodeConfig
from hrn_vo_ros.nodes.common import (
    CameraInfoInput,
    NoteLog,
    publish_diagnostics,
    qos,
    worst,
)
from hrn_vo_ros.nodes.params import declare_config
from hrn_vo_ros.nodes.process import run
from hrn_vo_ros.nodes.stats import NodeStats


class PacketizerNode(Node):
    """Event packets → binary frames (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('packetizer_node', **kwargs)
        self._algo = declare_config(self, PacketizerConfig, on_change=self._reconfigure)
        self._opts = declare_config(self, PacketizerNodeConfig)
        opts, cfg = self._opts.config, self._algo.config
        self.stats = NodeStats()
        self._stream = PacketStream(cfg, sensor_size=opts.sensor_size, clock=opts.clock,
                                    counts=self.stats.counts)
        self._reader = ros_msgs.PacketReader()
        self._camera_info = (CameraInfoInput(self, self._on_camera_info)
                             if self._stream.needs_camera_info else None)
        self._note = NoteLog(self, self.stats, lambda: self._opts.config.log_throttle_s)
        self._reject = self._note.reject
        self._pub = self.create_publisher(Image, '~/frames', qos(opts.frames_depth))
        self._diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_subscription(EventPacket, '~/events', self._on_events,
                                 qos(opts.events_depth, reliable=opts.events_reliable,
                                     keep_all=opts.events_keep_all))
        self.create_timer(opts.diagnostics_period_s, self._on_timer)
        self.get_logger().info(self._stream.describe(
            events_reliable=opts.events_reliable,
            camera_info_topic=self.resolve_topic_name('~/camera_info')))

    def _reconfigure(self, cfg: PacketizerConfig) -> None:
        """A tunable changed: start a new packetizer (pending events are dropped)."""
        try:
            if not self._stream.reconfigure(cfg):   # still waiting: applied when it can
                return
        except HrnVoError as err:
            self._reject('reconfigure', err)
            return
        self.get_logger().info(f'packetizer reconfigured: {cfg}')

    def _on_camera_info(self, msg: CameraInfo) -> None:
        if self._stream.packetizer is not None:
            return
        try:
            out = self._stream.calibrate(ros_msgs.camera_info_to_calibration(msg))
        except HrnVoError as err:
            self._reject('camera_info', err)
            return
        self._publish(out)

    def _on_events(self, msg: EventPacket) -> None:
        t0 = time.perf_counter()
        self.stats.count('packets_in')
        missed = self.stats.sequence(int(msg.seq))
        if missed:
            self.get_logger().warning(f'{missed} event packet(s) lost before seq {msg.seq} '
                                      f'({self.stats.seq_gaps} so far)',
                                      throttle_duration_sec=self._opts.config.log_throttle_s)
        try:
            header_ns, ev = self._reader.read(msg)
        except DECODE_ERRORS as err:
            self._reject('decode', err)
            return
        out = self._stream.push(header_ns, ev, seq=int(msg.seq), size=self._reader.size(msg),
                                redecode=lambda: self._reader.reread(msg),
                                wait_events=self._opts.config.camera_info_wait_events)
        self._publish(out)
        if out.accepted:
            self.stats.processing(time.perf_counter() - t0)

    def _publish(self, out: StreamOutput) -> None:
        """Log the notes (:class:`NoteLog`), then publish the frames."""
        for note in out.notes:
            self._note(note)
        frame_id = self._opts.config.frame_id
        for stamp, image in out.frames:
            try:
                self._pub.publish(ros_msgs.frame_to_image(image, stamp, frame_id))
            except HrnVoError as err:   # a stamp before 1970 (clock.stamps: sensor)
                self._reject('stamp', err)

    def _on_timer(self) -> None:
        extra = self._stream.diagnostic_values(f'{self.stats.rate("frames_out"):.1f}',
                                               self._pub.get_subscription_count())
        if self._stream.packetizer is None and self._camera_info is not None:
            self._camera_info.recheck()
        window_s = self._opts.config.diagnostics_window_s
        level, message = worst(*self._stream.states(window_s))
        publish_diagnostics(self, self._diag, self.stats, extra, level=level, message=message,
                            window_s=window_s)


def main(args: list[str] | None = None) -> int:
    """Console script ``packetizer_node`` (``--ros-args`` are passed through)."""
    return run(PacketizerNode, args)


if __name__ == '__main__':
    sys.exit(main())
