"""Sensor clock → header clock (ROS time): a robust, drift-following offset with reset detection.

Every output of the node graph is stamped in the **header clock** of its input stream (the
``header.stamp`` of the driver's messages: ROS time for a live driver, the sensor time itself in
bags written by ``hrn-vo convert``). An event camera's own clock (``EventPacket.time_base`` +
per-event offsets; a Prophesee evt3 sensor counts from camera start) is only used *within* a
stream: it orders events and spaces frames. :class:`StreamClock` maps it to the header clock.

Mapping. Each packet gives one sample ``o = header - sensor_first`` (drivers and the converter
stamp a packet with the time of its first event, its ``time_base``). Host stamps carry a
positive, jittery latency, so the offset is the **minimum** of the samples of the last
``window_s`` seconds of header time: latency jitter does not move it. A new, lower minimum is
taken at once; when the minimum rises (the clocks drift apart, or a low sample left the window)
the offset follows at most at ``max_slew`` seconds per second, so stamps stay smooth. Mapped
stamps of one stream never decrease (a decrease of the offset is absorbed by holding the last
stamp) until a reset. With header = sensor time the offset is exactly 0 and stamps are the
sensor times (a converted bag reproduces ``hrn-vo run``).

Resets. A packet whose sensor time goes back by more than ``backwards_tolerance_s`` (a driver
restart, a looped bag), whose header goes back by as much (a looped ``/clock``), or whose sensor
time advanced more than ``jump_tolerance_s`` beyond (or short of) the header's progress (one
far-future packet, a clock jump) **resets** the stream: its time state is dropped, the packet
starts a new mapping, the reset is counted (by cause) and the caller logs it (throttled) and
drops what it held from the old clock. A far-future packet thus costs two resets and nothing
else. Nothing is rejected forever. Sensor time going back by less than the tolerance (an overlap
of a few events) is a ``time_backwards`` packet: dropped alone, state kept. Equal stamps are fine.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
import enum
import math
import time

from hrn_vo_ros.core.configbase import param, validate

NS = 1_000_000_000


@dataclass(frozen=True, slots=True)
class ClockConfig:
    """How a stream's sensor time maps to its header clock (``core/clock.py``)."""

    stamps: str = param('header', 'Clock of the output stamps: header (the input header '
                        'clock, ROS time for a live driver) or sensor (the camera clock as is)',
                        choices=('header', 'sensor'))
    window_s: float = param(10.0, 'Window of the running minimum of header - sensor, seconds '
                            'of header time', lo=1e-3, hi=1e6)
    max_slew: float = param(1e-3, 'Fastest rise of the offset, seconds per second (clock '
                            'drift is about 1e-4); a lower minimum is taken at once',
                            lo=0.0, hi=1.0)
    backwards_tolerance_s: float = param(0.01, 'Sensor or header time going back by more '
                                         'than this resets the stream, seconds', lo=0.0,
                                         hi=1e6)
    jump_tolerance_s: float = param(1.0, 'Sensor progress differing from header progress by '
                                    'more than this resets the stream, seconds', lo=0.0,
                                    hi=1e9)

    def __post_init__(self) -> None:
        validate(self)


class Verdict(enum.Enum):
    """What :meth:`StreamClock.observe` made of one packet."""

    OK = 'ok'
    RESET = 'reset'          # the stream restarted from this packet (counted in ``resets``)
    BACKWARDS = 'backwards'  # a small step back: drop this packet, the state is kept


class StreamClock:
    """The header-clock mapping of one stream (see the module docstring).

    Args:
        cfg: The mapping settings.
    """

    def __init__(self, cfg: ClockConfig | None = None) -> None:
        self.cfg = cfg or ClockConfig()
        self.resets: Counter[str] = Counter()
        self.last_reason = ''
        self._samples: deque[tuple[int, int]] = deque()   # (header, offset), header ascending
        self._offset: int | None = None
        self._last_header: int | None = None
        self._last_sensor: int | None = None
        self._last_out: int | None = None

    @property
    def offset_ns(self) -> int | None:
        """The current offset header - sensor in ns (None before the first packet)."""
        return self._offset

    @property
    def reset_count(self) -> int:
        """Resets so far, all causes."""
        return sum(self.resets.values())

    def reset(self) -> None:
        """Forget the stream's time state (the next packet starts a new mapping)."""
        self._samples.clear()
        self._offset = self._last_header = self._last_sensor = self._last_out = None

    def _reason(self, header_ns: int, sensor_ns: int) -> str | None:
        """Why this packet starts a new mapping, or None."""
        if self._last_header is None or self._last_sensor is None:
            return None
        tol_back = int(self.cfg.backwards_tolerance_s * NS)
        d_sensor = sensor_ns - self._last_sensor
        d_header = header_ns - self._last_header
        if d_sensor < -tol_back:
            return 'sensor_backwards'
        if d_header < -tol_back:
            return 'header_backwards'
        if abs(d_sensor - d_header) > int(self.cfg.jump_tolerance_s * NS):
            return 'sensor_jump' if d_sensor > d_header else 'header_jump'
        return None

    def observe(self, header_ns: int, sensor_first_ns: int,
                sensor_last_ns: int | None = None) -> Verdict:
        """Feed one packet: its header stamp and its first (and last) event's sensor time.

        Returns:
            ``OK``; ``RESET`` when this packet starts a new mapping (the caller drops what it
            holds from the old clock); ``BACKWARDS`` for a small step back (drop the packet).
        """
        last = sensor_first_ns if sensor_last_ns is None else sensor_last_ns
        reason = self._reason(header_ns, sensor_first_ns)
        verdict = Verdict.OK
        if reason is not None:
            self.resets[reason] += 1
            self.last_reason = reason
            self.reset()
            verdict = Verdict.RESET
        elif self._last_sensor is not None and sensor_first_ns < self._last_sensor:
            return Verdict.BACKWARDS
        self._update(header_ns, header_ns - sensor_first_ns)
        self._last_header = header_ns if self._last_header is None else max(
            self._last_header, header_ns)
        self._last_sensor = max(last, sensor_first_ns)
        return verdict

    def _update(self, header_ns: int, sample: int) -> None:
        """Window minimum of the samples; rises slew-limited, drops at once."""
        window = int(self.cfg.window_s * NS)
        while self._samples and self._samples[-1][1] >= sample:
            self._samples.pop()                 # monotonic deque: the minimum is at the left
        self._samples.append((header_ns, sample))
        while self._samples[0][0] < header_ns - window:
            self._samples.popleft()
        target = self._samples[0][1]
        if self._offset is None or target <= self._offset:
            self._offset = target
        else:
            dt = 0 if self._last_header is None else max(0, header_ns - self._last_header)
            self._offset = min(target, self._offset + int(self.cfg.max_slew * dt))

    def to_header(self, sensor_ns: int) -> int:
        """The header-clock stamp of a sensor time of this stream (non-decreasing per stream).

        With ``stamps = sensor`` (or before any packet) the sensor time itself.
        """
        if self.cfg.stamps == 'sensor' or self._offset is None:
            return int(sensor_ns)
        out = int(sensor_ns) + self._offset
        if self._last_out is not None and out < self._last_out:
            out = self._last_out
        self._last_out = out
        return out


class StampChecker:
    """Reset detection for a stream stamped in its header clock already (IMU, frames).

    A stamp going back by more than ``tolerance_ns`` is a reset (counted; the caller clears its
    time state); by less (or equal to the previous when ``strict``) the message is dropped.
    """

    def __init__(self, tolerance_ns: int, *, strict: bool = False) -> None:
        self.tolerance_ns = int(tolerance_ns)
        self.strict = strict
        self.resets = 0
        self._last: int | None = None

    def observe(self, t_ns: int) -> Verdict:
        """Feed one stamp; see the class docstring."""
        last = self._last
        if last is not None and t_ns < last - self.tolerance_ns:
            self.resets += 1
            self._last = t_ns
            return Verdict.RESET
        if last is not None and (t_ns < last or (self.strict and t_ns == last)):
            return Verdict.BACKWARDS
        self._last = t_ns
        return Verdict.OK


class Recent:
    """When something last happened (wall time), with a detail, and whether that is recent.

    Diagnostics stay WARN or ERROR for a window after an event (a clock reset, a dropped frame)
    and are OK again once it has passed.

    Args:
        now: The wall clock in seconds (``time.monotonic``; injectable for tests).
    """

    def __init__(self, now: Callable[[], float] = time.monotonic) -> None:
        self._now = now
        self.at = -math.inf
        self.detail = ''

    def mark(self, detail: str = '') -> None:
        """It happened now."""
        self.at = self._now()
        self.detail = detail

    def within(self, window_s: float) -> bool:
        """Whether it happened at most ``window_s`` seconds ago."""
        return self._now() - self.at <= window_s


class RateLimit:
    """At most ``rate_hz`` events per second of wall time (the first one at once).

    Args:
        now: The wall clock in seconds (``time.monotonic``; injectable for tests).
    """

    def __init__(self, now: Callable[[], float] = time.monotonic) -> None:
        self._now = now
        self.last = 0.0

    def due(self, rate_hz: float) -> bool:
        """Whether an event may happen now (then it is taken as happened); never at 0 Hz."""
        now = self._now()
        if rate_hz <= 0.0 or now - self.last < 1.0 / rate_hz:
            return False
        self.last = now
        return True


class Throttle:
    """At most one event per ``period_s`` of wall time per key (the first one at once).

    Args:
        now: The wall clock in seconds (``time.monotonic``; injectable for tests).
    """

    def __init__(self, now: Callable[[], float] = time.monotonic) -> None:
        self._now = now
        self._last: dict[str, float] = {}

    def due(self, key: str, period_s: float) -> bool:
        """Whether an event of ``key`` may happen now (then it is taken as happened)."""
        now = self._now()
        last = self._last.get(key)
        if last is not None and now - last < period_s:
            return False
        self._last[key] = now
        return True
