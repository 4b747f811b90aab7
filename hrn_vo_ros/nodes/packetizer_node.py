"""``packetizer_node``: event packets in, binary event frames out.

Subscribes ``~/events`` (``event_camera_msgs/EventPacket``, mono or evt3; BEST_EFFORT depth 1000
as the drivers publish, RELIABLE with ``events_reliable``), bins fixed-count packets of events
with `core.events.frames.Packetizer` (a frame may span many messages, a message may
complete many frames) and publishes ``~/frames`` (``sensor_msgs/Image`` mono8 0/255, ``frame_id``
from a parameter). Sequence gaps, malformed packets and rates go to ``/diagnostics``.

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
"""

from __future__ import annotations

from dataclasses import replace
import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from event_camera_msgs.msg import EventPacket
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image

from hrn_vo_ros.core.clock import StreamClock, Verdict
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import Packetizer, PacketizerConfig, with_calibration
from hrn_vo_ros.core.events.sequence import CameraCalibration
from hrn_vo_ros.errors import HrnVoError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.eventpacket import PacketDecoder
from hrn_vo_ros.io.nodeconfig import PacketizerNodeConfig
from hrn_vo_ros.nodes.common import publish_diagnostics, qos, Rejects, run, worst
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
        self._sensor: tuple[int, int] | None = None   # sensor size taken from the messages
        self._camera_info_sub: Any = None
        self._camera_info_pubs = -1
        self._last_clock_reset_wall = -1e18
        cfg = self._algo.config
        if self._needs_camera_info(cfg):
            self._subscribe_camera_info()
        elif opts.sensor_size == 'config':
            self._packetizer = Packetizer(cfg)
        self._decoder = PacketDecoder()
        self._event_clock = StreamClock(opts.clock)
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

    def _subscribe_camera_info(self) -> None:
        """(Re)create the camera_info subscription: BEST_AVAILABLE resolves against the
        publishers present now, so it is re-resolved when they change (``_on_timer``)."""
        if self._camera_info_sub is not None:
            self.destroy_subscription(self._camera_info_sub)
        topic = self.resolve_topic_name('~/camera_info')
        self._camera_info_pubs = self.count_publishers(topic)
        latched_or_not = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_AVAILABLE,
                                    durability=DurabilityPolicy.BEST_AVAILABLE)
        self._camera_info_sub = self.create_subscription(
            CameraInfo, '~/camera_info', self._on_camera_info, latched_or_not)

    def _config(self, cfg: PacketizerConfig) -> PacketizerConfig:
        """``cfg`` with the sensor size of the messages and the camera_info calibration."""
        if self._sensor is not None:
            cfg = replace(cfg, sensor_width=self._sensor[0], sensor_height=self._sensor[1])
        if self._calib is not None:
            cfg = with_calibration(cfg, self._calib)
        return cfg

    def _ready(self) -> bool:
        """Whether frames can be made (calibration and sensor size known)."""
        if self._needs_camera_info(self._algo.config) and self._calib is None:
            return False
        return self._opts.config.sensor_size == 'config' or self._sensor is not None

    def _restart(self, why: str) -> None:
        """A new packetizer for the current settings (its pending events are dropped)."""
        if self._packetizer is not None:
            self.stats.count(f'dropped_on_{why}', self._packetizer.pending)
        self._packetizer = Packetizer(self._config(self._algo.config)) if self._ready() else None

    def _reconfigure(self, cfg: PacketizerConfig) -> None:
        """A tunable changed: start a new packetizer (pending events are dropped)."""
        if self._packetizer is None:     # still waiting for camera_info: applied when it comes
            return
        try:
            self._packetizer = Packetizer(self._config(cfg))
        except HrnVoError as err:
            self._reject('reconfigure', err)
            return
        self.get_logger().info(f'packetizer reconfigured: {cfg}')

    def _check_sensor_size(self, msg: EventPacket) -> None:
        """Sensor size from the packet (``sensor_size: messages``) or a warning on mismatch."""
        w, h = int(msg.width), int(msg.height)
        if w <= 0 or h <= 0:
            return
        cfg, opts = self._algo.config, self._opts.config
        if opts.sensor_size == 'config':
            if (w, h) != (cfg.sensor_width, cfg.sensor_height):
                self.stats.count('sensor_size_mismatch')
                self.get_logger().warning(
                    f'event packets say the sensor is {w}x{h}, the config says '
                    f'{cfg.sensor_width}x{cfg.sensor_height}: using the config (set '
                    'sensor_width/sensor_height, or sensor_size: messages)',
                    throttle_duration_sec=opts.log_throttle_s)
            return
        if self._sensor != (w, h):
            sized = replace(cfg, sensor_width=w, sensor_height=h)   # raises on a bad size
            fw, fh, ds = sized.width, sized.height, cfg.downsample
            first = self._sensor is None
            self._sensor = (w, h)
            self.get_logger().info(
                f'sensor size {w}x{h} from the event packets'
                + ('' if first else ' (changed: packetizer restarted)')
                + f': frames are {fw}x{fh} (downsample {ds:g}); the resonator width/height '
                'must be the same (config/live.yaml: 96x72 needs downsample '
                f'{w / 96:.4g} for this sensor)')
            if self._calib is not None and (self._calib.width, self._calib.height) != (w, h):
                self.get_logger().warning('camera_info is for another sensor size: waiting '
                                          'for a matching one')
                self._calib = None
            self._restart('sensor_size')

    def _on_camera_info(self, msg: CameraInfo) -> None:
        if self._packetizer is not None:
            return
        try:
            calib = ros_msgs.camera_info_to_calibration(msg)
            cfg = self._algo.config
            if self._sensor is not None:
                cfg = replace(cfg, sensor_width=self._sensor[0], sensor_height=self._sensor[1])
            elif self._opts.config.sensor_size == 'messages':
                cfg = replace(cfg, sensor_width=calib.width, sensor_height=calib.height)
            packetizer = Packetizer(with_calibration(cfg, calib))
        except HrnVoError as err:
            self._reject('camera_info', err)
            return
        self._calib = calib
        if self._sensor is None and self._opts.config.sensor_size == 'messages':
            self._sensor = (calib.width, calib.height)
        self._packetizer = packetizer
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
            header_ns = ros_msgs.stamp_to_ns(msg.header.stamp)
        except (HrnVoError, ValueError, TypeError, OverflowError) as err:
            self._reject('decode', err)
            return
        try:
            self._check_sensor_size(msg)
        except HrnVoError as err:          # a size no packetizer takes (over 65535)
            self._reject('sensor_size', err)
            return
        cfg = self._algo.config if self._packetizer is None else self._packetizer.cfg
        problem = packet_problem(ev, cfg, None)
        if problem is not None:
            self._reject(problem, f'seq {msg.seq}, {len(ev)} events')
            return
        verdict = self._event_clock.observe(header_ns, int(ev.t[0]), int(ev.t[-1]))
        if verdict is Verdict.BACKWARDS:
            self._reject('time_backwards', f'seq {msg.seq} starts before the previous packet '
                         'ended (by less than clock.backwards_tolerance_s)')
            return
        if verdict is Verdict.RESET:
            self._on_clock_reset(msg)
            restarted = self._restart_decoder(msg, header_ns, ev)
            if restarted is None:
                return
            ev = restarted
        self.stats.count('events_in', len(ev))
        if self._packetizer is None:
            self._hold(ev)
        else:
            self._push(ev)
        self.stats.processing(time.perf_counter() - t0)

    def _on_clock_reset(self, msg: EventPacket) -> None:
        """The sensor clock restarted or jumped: drop the old clock's partial frame, go on."""
        reason = self._event_clock.last_reason
        self.stats.count(f'clock_resets_{reason}')
        self._last_clock_reset_wall = time.monotonic()
        if self._packetizer is not None:
            self._restart('clock_reset')
        self.get_logger().warning(
            f'event clock reset ({reason}) at seq {msg.seq}: a driver restart, a looped bag '
            f'or a far-future packet ({self._event_clock.reset_count} so far); the time mapping '
            'restarts from this packet', throttle_duration_sec=self._opts.config.log_throttle_s)

    def _restart_decoder(self, msg: EventPacket, header_ns: int,
                         ev: EventArray) -> EventArray | None:
        """After a clock reset the decoder's stream state belongs to the old clock: drop it.

        An evt3 packet's times come from that state (a restarted camera's first TIME_HIGH
        would read as one more rollover of the old clock, +16.8 s), so the packet is decoded
        again from a fresh state and starts the new mapping with those times. Returns the
        packet's events, or None when nothing usable is left (counted).
        """
        self._decoder.reset()
        if str(msg.encoding) != 'evt3':
            return ev
        try:
            ev = ros_msgs.events_from_packet(msg, self._decoder)
        except (HrnVoError, ValueError, TypeError, OverflowError) as err:
            self._reject('decode', err)
            return None
        self._event_clock.reset()               # the mapping starts from the new times
        cfg = self._algo.config if self._packetizer is None else self._packetizer.cfg
        problem = packet_problem(ev, cfg, None)
        if problem is not None:                 # e.g. only words before the first time
            self.stats.count('dropped_on_decoder_reset', len(ev))
            return None
        self._event_clock.observe(header_ns, int(ev.t[0]), int(ev.t[-1]))
        return ev

    def _push(self, ev: EventArray) -> None:
        assert self._packetizer is not None
        try:
            frames = self._packetizer.push(ev)
        except HrnVoError as err:  # checked above; kept as the last line of defence
            self._reject('packetizer', err)
            return
        frame_id = self._opts.config.frame_id
        for f in frames:
            stamp = self._event_clock.to_header(f.t_ns)
            try:
                self._pub.publish(ros_msgs.frame_to_image(f.image, stamp, frame_id))
            except HrnVoError as err:   # a stamp before 1970 (clock.stamps: sensor)
                self._reject('stamp', err)
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
            ('frames_subscribers', self._pub.get_subscription_count()),
            ('sensor_size', '' if self._packetizer is None else
             f'{self._packetizer.cfg.sensor_width}x{self._packetizer.cfg.sensor_height}'),
            ('frame_size', '' if self._packetizer is None else
             f'{self._packetizer.cfg.width}x{self._packetizer.cfg.height}'),
            ('clock_offset_ns', self._event_clock.offset_ns),
            ('clock_resets', self._event_clock.reset_count)]
        opts = self._opts.config
        if self._packetizer is None and self._camera_info_sub is not None:
            pubs = self.count_publishers(self.resolve_topic_name('~/camera_info'))
            if pubs != self._camera_info_pubs:
                self._subscribe_camera_info()       # re-resolve the QoS for the new publishers
        states: list[tuple[str, str]] = []
        if self._packetizer is None:
            what = 'camera_info' if self._needs_camera_info(self._algo.config) \
                and self._calib is None else 'the sensor size'
            states.append(('warn', f'waiting for {what} ({self._waiting_n} events held)'))
        if time.monotonic() - self._last_clock_reset_wall <= opts.diagnostics_window_s:
            states.append(('warn', f'event clock reset ({self._event_clock.last_reason})'))
        level, message = worst(*states)
        publish_diagnostics(self, self._diag, self.stats, extra, level=level, message=message,
                            window_s=opts.diagnostics_window_s)


def main(args: list[str] | None = None) -> int:
    """Console script ``packetizer_node`` (``--ros-args`` are passed through)."""
    return run(PacketizerNode, args)


if __name__ == '__main__':
    sys.exit(main())
