"""One event-packet stream to frames stamped in its header clock: ``packetizer_node``'s logic.

:class:`PacketStream` combines what a live stream of event packets needs besides decoding:

* the packetizer (:class:`~hrn_vo_ros.core.events.frames.Packetizer`), restarted when the
  sensor size, the calibration or a tunable changes (its pending events dropped and counted as
  ``dropped_on_<why>``);
* the sensor size: ``sensor_size = 'config'`` keeps ``sensor_width``/``sensor_height`` and
  notes a mismatch; ``'messages'`` takes the packets' size (a later change restarts);
* the calibration of the first camera_info (with ``rectify`` and no ``calib.*``), events held
  until it arrives (at most ``wait_events``; older ones dropped and counted);
* the clock mapping (:class:`~hrn_vo_ros.core.clock.StreamClock`): a reset drops the old
  clock's partial frame and the decoder's stream state (the caller's ``redecode`` decodes the
  packet again from a fresh state), and the stream goes on.

Nothing here logs or publishes: each call returns a :class:`StreamOutput` with the frames
(header stamp, image), and :class:`Note` entries the caller logs or counts as rejects, in order.
Counters go to ``counts`` (shared with the node's book-keeping).
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.clock import ClockConfig, Recent, StreamClock, Verdict
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import Packetizer
from hrn_vo_ros.core.events.packet_config import (
    PacketizerConfig,
    VALIDATED_FRAME,
    with_calibration,
)
from hrn_vo_ros.core.events.sequence import CameraCalibration
from hrn_vo_ros.errors import HrnVoError

#: What a decoder raises on a malformed packet (counted as ``decode`` rejects).
DECODE_ERRORS = (HrnVoError, ValueError, TypeError, OverflowError)


def packet_problem(ev: EventArray, cfg: PacketizerConfig, last_t_ns: int | None) -> str | None:
    """Why a decoded event packet cannot be binned, as a short kind, or None if it can.

    Kinds: ``empty`` (no events), ``out_of_sensor`` (a coordinate outside the configured sensor
    size), ``time_backwards`` (starts before the previous packet ended or is unsorted inside).
    """
    if len(ev) == 0:
        return 'empty'
    if int(ev.x.max()) >= cfg.sensor_width or int(ev.y.max()) >= cfg.sensor_height:
        return 'out_of_sensor'
    if (last_t_ns is not None and int(ev.t[0]) < last_t_ns) or bool(np.any(np.diff(ev.t) < 0)):
        return 'time_backwards'
    return None


@dataclass(frozen=True, slots=True)
class Note:
    """Something for the caller to log or count.

    ``level`` is ``info``, ``warn`` or ``reject`` (a dropped message of kind ``kind``, counted
    by the caller). A ``throttled`` warning can repeat per message: the caller logs it at most
    once per throttle period per kind.
    """

    level: str
    kind: str
    text: str
    throttled: bool = False


@dataclass(slots=True)
class StreamOutput:
    """What one call produced: frames ``(header stamp ns, image)`` and notes, in order."""

    frames: list[tuple[int, NDArray[np.uint8]]] = field(default_factory=list)
    notes: list[Note] = field(default_factory=list)
    accepted: bool = False     # the packet's events were taken (binned or held)

    def reject(self, kind: str, detail: object) -> None:
        """Add a reject note."""
        self.notes.append(Note('reject', kind, str(detail)))


class PacketStream:
    """Event packets of one topic → frames in the header clock (see the module docstring).

    Args:
        cfg: The packetizer settings (``reconfigure`` replaces them).
        sensor_size: ``config`` or ``messages``.
        clock: The sensor → header clock mapping.
        counts: Where counters go (a new Counter when None).
        recent: Marks the last clock reset (wall time; injectable for tests).

    Raises:
        HrnVoError: if ``cfg`` makes no packetizer.
    """

    def __init__(self, cfg: PacketizerConfig, *, sensor_size: str = 'config',
                 clock: ClockConfig | None = None, counts: Counter[str] | None = None,
                 recent: Recent | None = None) -> None:
        self.cfg = cfg
        self.sensor_size = sensor_size
        self.clock = StreamClock(clock)
        self.counts: Counter[str] = Counter() if counts is None else counts
        self.last_reset = recent or Recent()
        self.calib: CameraCalibration | None = None
        self.sensor: tuple[int, int] | None = None     # sensor size taken from the messages
        self._held: deque[EventArray] = deque()
        self.held = 0
        self.packetizer: Packetizer | None = Packetizer(cfg) if self._ready() else None

    @property
    def needs_camera_info(self) -> bool:
        """Whether the calibration must come from a camera_info (rectify, no ``calib.*``)."""
        return self.cfg.rectify != 'none' and not self.cfg.calib.known

    def describe(self, *, events_reliable: bool, camera_info_topic: str) -> str:
        """The node's start-up line: packet size, sensor and frame size, rectification (and
        the wait for a camera_info on ``camera_info_topic``), the events' QoS, the rate cap."""
        cfg = self.cfg
        waiting = ('' if not self.needs_camera_info else ' (no calib.* parameters: events are '
                   f'held until a camera_info arrives on {camera_info_topic})')
        size = (f'{cfg.sensor_width}x{cfg.sensor_height} -> {cfg.width}x{cfg.height}'
                if self.sensor_size == 'config' else 'sensor size from the event packets')
        cap = (f', above {cfg.events_per_frame * cfg.max_frame_hz / 1e6:.3g} M events/s an '
               'even share binned (max_frame_hz)' if cfg.max_frame_hz > 0 else '')
        return (f'{cfg.events_per_frame} events per frame, {size}, rectify {cfg.rectify}'
                f'{waiting}, events {"reliable" if events_reliable else "best effort"}{cap}')

    def _ready(self) -> bool:
        """Whether frames can be made (calibration and sensor size known)."""
        if self.needs_camera_info and self.calib is None:
            return False
        return self.sensor_size == 'config' or self.sensor is not None

    def _config(self, cfg: PacketizerConfig) -> PacketizerConfig:
        """``cfg`` with the sensor size of the messages and the camera_info calibration."""
        if self.sensor is not None:
            cfg = replace(cfg, sensor_width=self.sensor[0], sensor_height=self.sensor[1])
        if self.calib is not None:
            cfg = with_calibration(cfg, self.calib)
        return cfg

    def _binning(self) -> PacketizerConfig:
        return self.cfg if self.packetizer is None else self.packetizer.cfg

    def _restart(self, why: str) -> None:
        """A new packetizer for the current settings (its pending events are dropped)."""
        if self.packetizer is not None:
            self.counts[f'dropped_on_{why}'] += self.packetizer.pending
        self.packetizer = Packetizer(self._config(self.cfg)) if self._ready() else None

    def reconfigure(self, cfg: PacketizerConfig) -> bool:
        """New settings; a new packetizer (pending events dropped) unless still waiting.

        Returns:
            Whether a packetizer was restarted (False while waiting: applied later).

        Raises:
            HrnVoError: if ``cfg`` makes no packetizer (the old one is kept).
        """
        self.cfg = cfg
        if self.packetizer is None:
            return False
        self.packetizer = Packetizer(self._config(cfg))
        return True

    def calibrate(self, calib: CameraCalibration) -> StreamOutput:
        """The camera_info's calibration: start binning, the held events first.

        Raises:
            HrnVoError: if no packetizer takes it (nothing changes).
        """
        cfg = self.cfg
        if self.sensor is not None:
            cfg = replace(cfg, sensor_width=self.sensor[0], sensor_height=self.sensor[1])
        elif self.sensor_size == 'messages':
            cfg = replace(cfg, sensor_width=calib.width, sensor_height=calib.height)
        packetizer = Packetizer(with_calibration(cfg, calib))
        self.calib = calib
        if self.sensor is None and self.sensor_size == 'messages':
            self.sensor = (calib.width, calib.height)
        self.packetizer = packetizer
        out = StreamOutput()
        out.notes.append(Note('info', 'camera_info', (
            f'camera_info: fx {calib.fx:.1f} fy {calib.fy:.1f} cx {calib.cx:.1f} '
            f'cy {calib.cy:.1f} dist {list(calib.dist)}; rectifying, {self.held} held '
            'events go first')))
        held, self._held, self.held = self._held, deque(), 0
        for ev in held:
            self._bin(ev, out)
        return out

    def _check_size(self, w: int, h: int, out: StreamOutput) -> None:
        """Sensor size from the packet (``sensor_size = messages``) or a note on mismatch."""
        if w <= 0 or h <= 0:
            return
        cfg = self.cfg
        if self.sensor_size == 'config':
            if (w, h) != (cfg.sensor_width, cfg.sensor_height):
                self.counts['sensor_size_mismatch'] += 1
                out.notes.append(Note('warn', 'sensor_size_mismatch', (
                    f'event packets say the sensor is {w}x{h}, the config says '
                    f'{cfg.sensor_width}x{cfg.sensor_height}: using the config (set '
                    'sensor_width/sensor_height, or sensor_size: messages)'), throttled=True))
            return
        if self.sensor != (w, h):
            sized = replace(cfg, sensor_width=w, sensor_height=h)   # raises on a bad size
            fw, fh, ds = sized.width, sized.height, sized.factor
            first = self.sensor is None
            self.sensor = (w, h)
            vw, vh = VALIDATED_FRAME
            auto = cfg.downsample == 0
            factor = f'{ds:.4g}, auto' if auto else f'{ds:.4g}'
            validated = '' if auto else (f' ({vw}x{vh}, the validated size, needs downsample '
                                         f'{w / vw:.4g} here, or 0: auto)')
            out.notes.append(Note('info', 'sensor_size', (
                f'sensor size {w}x{h} from the event packets'
                + ('' if first else ' (changed: packetizer restarted)')
                + f': frames are {fw}x{fh} (downsample {factor}); a resonator with '
                'frame_size: frames (the live configs) takes that size, else its width/height '
                f'must be the same{validated}')))
            if self.calib is not None and (self.calib.width, self.calib.height) != (w, h):
                out.notes.append(Note('warn', 'camera_info_size', 'camera_info is for another '
                                      'sensor size: waiting for a matching one'))
                self.calib = None
            self._restart('sensor_size')

    def push(self, header_ns: int, ev: EventArray, *, seq: int, size: tuple[int, int],
             redecode: Callable[[], EventArray | None], wait_events: int) -> StreamOutput:
        """One decoded packet: checked, clock-mapped, binned (or held until camera_info).

        Args:
            header_ns: The packet's header stamp.
            ev: Its events (sensor time).
            seq: Its sequence number (for the notes).
            size: The sensor width and height the packet gives (0 when it gives none).
            redecode: After a clock reset: resets the decoder's stream state and decodes the
                packet again, or returns None when the encoding has no such state.
            wait_events: How many events to hold at most while waiting for camera_info.
        """
        out = StreamOutput()
        try:
            self._check_size(size[0], size[1], out)
        except HrnVoError as err:          # a size no packetizer takes (over 65535)
            out.reject('sensor_size', err)
            return out
        problem = packet_problem(ev, self._binning(), None)
        if problem is not None:
            out.reject(problem, f'seq {seq}, {len(ev)} events')
            return out
        verdict = self.clock.observe(header_ns, int(ev.t[0]), int(ev.t[-1]))
        if verdict is Verdict.BACKWARDS:
            out.reject('time_backwards', f'seq {seq} starts before the previous packet ended '
                       '(by less than clock.backwards_tolerance_s)')
            return out
        if verdict is Verdict.RESET:
            self._on_clock_reset(seq, out)
            restarted = self._restart_decoder(header_ns, ev, redecode, out)
            if restarted is None:
                return out
            ev = restarted
        self.counts['events_in'] += len(ev)
        out.accepted = True
        if self.packetizer is None:
            self._hold(ev, wait_events, out)
        else:
            self._bin(ev, out)
        return out

    def _on_clock_reset(self, seq: int, out: StreamOutput) -> None:
        """The sensor clock restarted or jumped: drop the old clock's partial frame, go on."""
        reason = self.clock.last_reason
        self.counts[f'clock_resets_{reason}'] += 1
        self.last_reset.mark(reason)
        if self.packetizer is not None:
            self._restart('clock_reset')
        out.notes.append(Note('warn', 'clock_reset', (
            f'event clock reset ({reason}) at seq {seq}: a driver restart, a looped bag '
            f'or a far-future packet ({self.clock.reset_count} so far); the time mapping '
            'restarts from this packet'), throttled=True))

    def _restart_decoder(self, header_ns: int, ev: EventArray,
                         redecode: Callable[[], EventArray | None],
                         out: StreamOutput) -> EventArray | None:
        """After a clock reset the decoder's stream state belongs to the old clock: drop it.

        An evt3 packet's times come from that state (a restarted camera's first TIME_HIGH
        would read as one more rollover of the old clock, +16.8 s), so the packet is decoded
        again from a fresh state and starts the new mapping with those times. Returns the
        packet's events, or None when nothing usable is left (counted).
        """
        try:
            again = redecode()
        except DECODE_ERRORS as err:
            out.reject('decode', err)
            return None
        if again is None:
            return ev
        self.clock.reset()                      # the mapping starts from the new times
        if packet_problem(again, self._binning(), None) is not None:
            self.counts['dropped_on_decoder_reset'] += len(again)   # e.g. only words before
            return None                                             # the first time
        self.clock.observe(header_ns, int(again.t[0]), int(again.t[-1]))
        return again

    def _hold(self, ev: EventArray, limit: int, out: StreamOutput) -> None:
        """Keep events until camera_info arrives, dropping the oldest beyond the limit."""
        self._held.append(ev)
        self.held += len(ev)
        while self.held > limit and self._held:
            old = self._held.popleft()
            self.held -= len(old)
            self.counts['dropped_waiting_for_camera_info'] += len(old)
            dropped = self.counts['dropped_waiting_for_camera_info']
            out.notes.append(Note('warn', 'waiting', (
                f'no camera_info yet ({dropped} events dropped so far): publish it on '
                '~/camera_info, set the calib.* parameters or set rectify to none'),
                throttled=True))

    def _bin(self, ev: EventArray, out: StreamOutput) -> None:
        assert self.packetizer is not None
        try:
            frames = self.packetizer.push(ev)
        except HrnVoError as err:  # checked above; kept as the last line of defence
            out.reject('packetizer', err)
            return
        out.frames += [(self.clock.to_header(f.t_ns), f.image) for f in frames]
        self.counts['frames_out'] += len(frames)

    def diagnostic_values(self, frame_rate_hz: str,
                          frames_subscribers: int) -> list[tuple[str, object]]:
        """The stream's diagnostics key/values (with the two the caller measures)."""
        p = self.packetizer
        return [
            ('frame_rate_hz', frame_rate_hz),
            ('pending_events', 0 if p is None else p.pending),
            ('rectify', self.cfg.rectify),
            ('waiting_for_camera_info', p is None),
            ('events_held', self.held),
            ('events_outside_frame', 0 if p is None else p.outside),
            ('events_denoised', 0 if p is None else p.denoised),
            ('events_capped', 0 if p is None else p.capped),
            ('frames_by_time', 0 if p is None else p.by_time),
            ('rate_cap_share', '' if p is None else f'{p.cap_share:.3f}'),
            ('background_hz', '' if p is None or p.background_hz is None
             else f'{p.background_hz:.3f}'),
            ('background_share', '' if p is None or p.background_share is None
             else f'{p.background_share:.3f}'),
            ('noisy_threshold', p is not None and p.noisy),
            ('frames_subscribers', frames_subscribers),
            ('sensor_size', '' if p is None else f'{p.cfg.sensor_width}x{p.cfg.sensor_height}'),
            ('frame_size', '' if p is None else f'{p.cfg.width}x{p.cfg.height}'),
            ('clock_offset_ns', self.clock.offset_ns),
            ('clock_resets', self.clock.reset_count)]

    def states(self, window_s: float) -> list[tuple[str, str]]:
        """``(level, message)`` of the stream now: WARN while waiting or after a clock reset."""
        states: list[tuple[str, str]] = []
        if self.packetizer is None:
            what = ('camera_info' if self.needs_camera_info and self.calib is None
                    else 'the sensor size')
            states.append(('warn', f'waiting for {what} ({self.held} events held)'))
        if self.last_reset.within(window_s):
            states.append(('warn', f'event clock reset ({self.clock.last_reason})'))
        return states
