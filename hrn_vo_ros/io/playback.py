"""Bag playback timing, free of ROS: when each record is due and when ``/clock`` ticks.

A record with bag time ``t`` is due at wall time (monotonic seconds)

    w(t) = w0 + (t - t0) / (1e9 * rate)

where ``t0`` is the first record's bag time and ``w0`` the wall time playback started; with
``max_rate`` every record is due at once (reliable subscribers pace the publisher instead).
``/clock`` carries the bag time of the record about to be published, at most ``clock_hz`` times
per wall second, never going backwards (for ``use_sim_time`` nodes).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
import time

from hrn_vo_ros.core.configbase import param, validate
from hrn_vo_ros.errors import BagError


@dataclass(frozen=True, slots=True)
class PlaybackConfig:
    """Options of the bag player (``hrn-vo play`` and the ``bag_player`` node)."""

    bag: str = param('', 'ROS 2 bag directory to play', read_only=True)
    rate: float = param(1.0, 'Playback speed factor (1 = real time)', lo=1e-3, hi=1e3,
                        read_only=True)
    max_rate: bool = param(False, 'Ignore the recorded timing: publish as fast as the '
                           'writers allow (RELIABLE, KEEP_ALL: reliable subscribers pace it)',
                           read_only=True)
    reliable: bool = param(False, 'Publish every topic RELIABLE (recorded best-effort topics '
                           'do not match reliable subscribers otherwise)', read_only=True)
    topics: tuple[str, ...] = param((), 'Topics to play (empty: all)', read_only=True)
    clock: bool = param(False, 'Publish /clock (rosgraph_msgs/Clock) following the bag time',
                        read_only=True)
    clock_hz: float = param(100.0, 'Largest /clock rate, per wall second', lo=1.0, hi=10000.0,
                            read_only=True)
    wait_for_subscribers: int = param(0, 'Wait until every event topic has this many '
                                      'subscribers before starting', lo=0, hi=1000,
                                      read_only=True)
    wait_topics: tuple[str, ...] = param((), 'Topics wait_for_subscribers waits on (empty: the '
                                         'event topics), e.g. the IMU topic too, so that its '
                                         'first samples are not lost', read_only=True)
    wait_timeout_s: float = param(30.0, 'Give up waiting for subscribers after this, seconds',
                                  lo=0.0, hi=3600.0, read_only=True)
    ack_timeout_s: float = param(5.0, 'Longest wait for reliable subscribers: at the end to '
                                 'acknowledge everything, and at max_rate for a lagging one to '
                                 'take the next message, seconds', lo=0.001, hi=600.0,
                                 read_only=True)

    def __post_init__(self) -> None:
        validate(self)


class PlaybackSchedule:
    """Due times of records and ``/clock`` ticks (see the module docstring).

    Args:
        t0_ns: Bag time of the first record.
        start_wall_s: Wall time (monotonic seconds) at which that record is due.
        rate: Speed factor; None for "as fast as possible".
        clock_hz: Largest ``/clock`` rate per wall second.
    """

    def __init__(self, t0_ns: int, start_wall_s: float, *, rate: float | None,
                 clock_hz: float = 100.0) -> None:
        self.t0_ns = t0_ns
        self.start_wall_s = start_wall_s
        self.rate = rate
        self.clock_period_s = 1.0 / clock_hz
        self._last_clock_wall = -float('inf')
        self._last_clock_ns: int | None = None

    def due(self, t_ns: int) -> float:
        """Wall time at which the record with bag time ``t_ns`` is due."""
        if self.rate is None:
            return self.start_wall_s
        return self.start_wall_s + (t_ns - self.t0_ns) / (1e9 * self.rate)

    def bag_time_at(self, wall_s: float) -> int:
        """Bag time that corresponds to wall time ``wall_s`` (real-time modes)."""
        if self.rate is None:
            return self.t0_ns
        return self.t0_ns + round((wall_s - self.start_wall_s) * 1e9 * self.rate)

    def clock_tick(self, t_ns: int, wall_s: float, *, force: bool = False) -> int | None:
        """The ``/clock`` value to publish before a record at ``t_ns`` (None: no tick now).

        Ticks at the first record, then whenever the bag time advanced and a clock period of
        wall time passed (or ``force``, e.g. for the last record). Never goes backwards.
        """
        last = self._last_clock_ns
        if last is not None and t_ns <= last:
            return None
        if last is not None and not force and wall_s - self._last_clock_wall < \
                self.clock_period_s:
            return None
        self._last_clock_ns = t_ns
        self._last_clock_wall = wall_s
        return t_ns


def play(records: Iterable[tuple[str, int, bytes]], publish: Callable[[str, bytes], None], *,
         rate: float | None, clock: Callable[[int], None] | None = None,
         clock_hz: float = 100.0, now: Callable[[], float] = time.monotonic,
         sleep: Callable[[float], None] = time.sleep) -> dict[str, int]:
    """Publish ``(topic, bag time ns, payload)`` records on time (the player's loop, ROS-free).

    Sleeps until each record is due (:class:`PlaybackSchedule`), ticks ``clock`` before it when
    a tick is due, and ticks once more with the last bag time at the end.

    Args:
        records: In bag-time order.
        publish: Sends one payload on a topic.
        rate: Speed factor, None for as fast as ``publish`` returns.
        clock: Receives ``/clock`` values (ns), or None.
        clock_hz: Largest clock rate per wall second.
        now: Wall clock (monotonic seconds); injectable for tests.
        sleep: Sleeps that many seconds; injectable for tests.

    Returns:
        Records published per topic.
    """
    sent: dict[str, int] = {}
    schedule: PlaybackSchedule | None = None
    last_t: int | None = None
    for topic, t_ns, raw in records:
        if schedule is None:
            schedule = PlaybackSchedule(t_ns, now(), rate=rate, clock_hz=clock_hz)
        delay = schedule.due(t_ns) - now()
        if delay > 0:
            sleep(delay)
        if clock is not None:
            tick = schedule.clock_tick(t_ns, now())
            if tick is not None:
                clock(tick)
        publish(topic, raw)
        sent[topic] = sent.get(topic, 0) + 1
        last_t = t_ns
    if clock is not None and schedule is not None and last_t is not None:
        tick = schedule.clock_tick(last_t, now(), force=True)
        if tick is not None:
            clock(tick)
    return sent


def publish_retrying(publish: Callable[[bytes], None], raw: bytes, timeout_s: float, *,
                     retry_on: type[Exception], now: Callable[[], float] = time.monotonic,
                     sleep: Callable[[float], None] = time.sleep) -> int:
    """Publish, retrying while the middleware reports a full KEEP_ALL history.

    A RELIABLE KEEP_ALL writer blocks on a full history and raises (rclpy: ``RCLError``, passed
    as ``retry_on``) after its blocking time (Fast DDS: 100 ms) when a reader lags; at
    ``max_rate`` that is back pressure, not a failure, so the message is offered again until
    ``timeout_s`` without progress.

    Returns:
        The number of retries.

    Raises:
        BagError: if the readers do not take the message within ``timeout_s``.
    """
    deadline = now() + timeout_s
    retries = 0
    while True:
        try:
            publish(raw)
            return retries
        except retry_on as err:
            if now() > deadline:
                raise BagError(f'a subscriber took no message for {timeout_s} s at max_rate '
                               f'({err}); raise ack_timeout_s or drop --max-rate') from None
            retries += 1
            sleep(0.005)
