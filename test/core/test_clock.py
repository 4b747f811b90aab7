"""The sensor → header clock mapping on hand-made streams (core/clock.py)."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.clock import (
    ClockConfig,
    RateLimit,
    Recent,
    StampChecker,
    StreamClock,
    Throttle,
    Verdict,
)
from hrn_vo_ros.errors import ConfigError

MS = 1_000_000
S = 1_000_000_000
T0 = 1_760_000_000 * S                    # header clock: ROS time near now


def feed(clock: StreamClock, headers: np.ndarray, sensors: np.ndarray,
         period: int = 5 * MS) -> list[Verdict]:
    return [clock.observe(int(h), int(s), int(s) + period - 1)
            for h, s in zip(headers, sensors, strict=True)]


def test_constant_offset_maps_exactly_and_jitter_does_not_move_it(
        rng: np.random.Generator) -> None:
    clock = StreamClock()
    sensor = np.arange(2000) * 5 * MS + 3 * S      # sensor clock counts from camera start
    jitter = rng.integers(0, 4 * MS, len(sensor))
    jitter[::50] = 0                               # now and then a packet with no latency
    assert all(v is Verdict.OK for v in feed(clock, T0 + sensor - 3 * S + jitter, sensor))
    assert clock.offset_ns == T0 - 3 * S
    assert clock.to_header(int(sensor[-1]) + 2 * MS) == T0 + sensor[-1] - 3 * S + 2 * MS
    assert clock.reset_count == 0


def test_header_equal_to_sensor_is_the_identity() -> None:
    clock = StreamClock()
    sensor = np.arange(100) * 5 * MS
    feed(clock, sensor, sensor)
    assert clock.offset_ns == 0 and clock.to_header(123) == 123


def test_drift_is_followed_within_a_millisecond() -> None:
    clock = StreamClock(ClockConfig(window_s=2.0))
    sensor = np.arange(12000) * 5 * MS             # 60 s
    for drift in (1e-4, -1e-4):
        clock.reset()
        headers = T0 + sensor + (sensor * drift).astype(np.int64)
        feed(clock, headers, sensor)
        t = int(sensor[-1])
        assert abs(clock.to_header(t) - int(headers[-1])) < 1 * MS
    assert clock.reset_count == 0


def test_restart_resets_and_maps_the_new_clock() -> None:
    clock = StreamClock()
    sensor = np.arange(400) * 5 * MS
    headers = T0 + sensor
    verdicts = feed(clock, headers[:200], sensor[:200] + 10 * S)
    verdicts += feed(clock, headers[200:], sensor[200:] - sensor[200])  # driver restart
    assert verdicts[200] is Verdict.RESET and verdicts.count(Verdict.RESET) == 1
    assert clock.resets['sensor_backwards'] == 1
    assert clock.to_header(int(sensor[-1] - sensor[200])) == int(headers[-1])


def test_one_far_future_packet_costs_two_resets_and_nothing_more() -> None:
    clock = StreamClock()
    sensor = np.arange(300) * 5 * MS
    headers = T0 + sensor
    sensor_bad = sensor.copy()
    sensor_bad[150] += 10_000 * S
    verdicts = feed(clock, headers, sensor_bad)
    assert verdicts[150] is Verdict.RESET and verdicts[151] is Verdict.RESET
    assert verdicts.count(Verdict.RESET) == 2 and verdicts.count(Verdict.BACKWARDS) == 0
    assert clock.resets == {'sensor_jump': 1, 'sensor_backwards': 1}
    # the far-future packet itself maps to its header time
    assert abs(clock.to_header(int(sensor[-1])) - int(headers[-1])) == 0


def test_equal_timestamps_and_small_overlaps() -> None:
    clock = StreamClock()
    assert clock.observe(T0, 100, 100) is Verdict.OK
    assert clock.observe(T0, 100, 100) is Verdict.OK           # equal header and sensor
    assert clock.to_header(100) == clock.to_header(100) == T0
    assert clock.observe(T0 + MS, 50, 200) is Verdict.BACKWARDS  # 50 ns back: drop it only
    assert clock.observe(T0 + 2 * MS, 2 * MS, 2 * MS) is Verdict.OK
    assert clock.reset_count == 0


def test_stamps_never_decrease_within_a_stream() -> None:
    clock = StreamClock()
    clock.observe(T0 + 3 * MS, 0)                   # a late first sample
    a = clock.to_header(1 * MS)
    clock.observe(T0 + 5 * MS, 5 * MS)              # a lower offset: 3 ms less
    assert clock.offset_ns == T0
    assert clock.to_header(2 * MS) == a             # held, not back in time
    assert clock.to_header(10 * MS) == T0 + 10 * MS


def test_header_going_back_resets() -> None:
    clock = StreamClock()
    clock.observe(T0 + 10 * S, 0)
    assert clock.observe(T0, 5 * MS) is Verdict.RESET
    assert clock.resets['header_backwards'] == 1 and clock.to_header(5 * MS) == T0


def test_sensor_stamps_mode() -> None:
    clock = StreamClock(ClockConfig(stamps='sensor'))
    clock.observe(T0, 7)
    assert clock.to_header(9) == 9


def test_stamp_checker() -> None:
    check = StampChecker(10 * MS, strict=True)
    assert check.observe(T0) is Verdict.OK
    assert check.observe(T0) is Verdict.BACKWARDS
    assert check.observe(T0 - MS) is Verdict.BACKWARDS
    assert check.observe(T0 + MS) is Verdict.OK
    assert check.observe(5) is Verdict.RESET and check.resets == 1
    assert check.observe(6) is Verdict.OK


def test_config_is_validated() -> None:
    with pytest.raises(ConfigError):
        ClockConfig(stamps='gps')


def test_recent_marks_an_event_for_a_window() -> None:
    now = [100.0]
    recent = Recent(lambda: now[0])
    assert not recent.within(1e9)                   # never happened
    recent.mark('sensor_backwards')
    assert recent.within(0.0) and recent.detail == 'sensor_backwards'
    now[0] += 10.0
    assert recent.within(10.0) and not recent.within(9.99)


def test_rate_limit_lets_the_first_through_then_one_per_period() -> None:
    now = [0.0]
    rate = RateLimit(lambda: now[0])
    assert not rate.due(0.0)                        # 0 Hz: never
    now[0] = 5.0
    assert rate.due(2.0) and not rate.due(2.0)
    now[0] = 5.49
    assert not rate.due(2.0)
    now[0] = 5.5
    assert rate.due(2.0)


def test_throttle_is_per_key() -> None:
    now = [0.0]
    throttle = Throttle(lambda: now[0])
    assert throttle.due('a', 5.0) and not throttle.due('a', 5.0)
    assert throttle.due('b', 5.0)                   # another kind is not held back
    now[0] = 4.9
    assert not throttle.due('a', 5.0)
    now[0] = 5.0
    assert throttle.due('a', 5.0) and throttle.due('c', 0.0) and throttle.due('c', 0.0)


def test_a_rising_minimum_is_followed_at_max_slew_only() -> None:
    """A low sample that leaves the window raises the minimum from 0 to 5 ms of latency: the
    offset rises by max_slew x header time from the first packet without that sample (10 us
    per 10 ms packet here), not at once."""
    clock = StreamClock(ClockConfig(window_s=1.0, max_slew=1e-3))
    clock.observe(T0, 0)                            # no latency
    for k in range(1, 200):                         # 5 ms latency, a packet every 10 ms
        clock.observe(T0 + k * 10 * MS + 5 * MS, k * 10 * MS)
        if k == 99:                                 # the first sample is still in the window
            assert clock.offset_ns == T0
    # k = 100..199: 100 packets of 10 ms, each adding int(1e-3 x 10 ms) = 10 us
    assert clock.offset_ns == T0 + 100 * int(1e-3 * 10 * MS)


def test_window_and_tolerance_bounds_are_inclusive() -> None:
    """A sample exactly window_s old is still in the window; a step back by exactly the
    backwards tolerance is no reset; progress differing by exactly the jump tolerance is none;
    a pause of both clocks is no jump."""
    clock = StreamClock(ClockConfig(window_s=1.0))
    clock.observe(T0, 0)
    clock.observe(T0 + S, S - 5 * MS)               # header exactly window_s later
    assert clock.offset_ns == T0
    clock = StreamClock(ClockConfig(backwards_tolerance_s=0.01))
    clock.observe(T0, 100 * MS)
    assert clock.observe(T0 + MS, 90 * MS) is Verdict.BACKWARDS     # 10 ms back: dropped
    assert clock.observe(T0 - 10 * MS, 101 * MS) is Verdict.OK      # header 10 ms back
    assert clock.observe(T0 - 10 * MS - 1, 102 * MS) is Verdict.RESET
    clock = StreamClock(ClockConfig(jump_tolerance_s=1.0))
    clock.observe(T0, 0)
    assert clock.observe(T0 + 10 * MS, 10 * MS + S) is Verdict.OK   # exactly 1 s more
    assert clock.observe(T0 + 20 * MS, 20 * MS + 2 * S + 1) is Verdict.RESET
    clock = StreamClock()
    clock.observe(T0, 0)
    assert clock.observe(T0 + 3 * S, 3 * S) is Verdict.OK           # a 3 s pause of both
    assert clock.reset_count == 0


def test_the_next_packet_must_start_after_the_last_event_seen() -> None:
    """The events of a packet reach to its last one: a packet starting before that (an
    overlap within the backwards tolerance) is dropped, one starting at it is fine."""
    clock = StreamClock()
    clock.observe(T0, 100 * MS, 200 * MS)
    assert clock.observe(T0 + MS, 195 * MS, 250 * MS) is Verdict.BACKWARDS
    assert clock.observe(T0 + 2 * MS, 200 * MS, 260 * MS) is Verdict.OK


def test_stamp_checker_bounds() -> None:
    """Not strict: an equal stamp is fine; a stamp back by exactly the tolerance is dropped,
    by more it resets."""
    check = StampChecker(10 * MS)
    assert check.observe(T0) is Verdict.OK and check.observe(T0) is Verdict.OK
    assert check.observe(T0 - 10 * MS) is Verdict.BACKWARDS
    assert check.observe(T0 - 10 * MS - 1) is Verdict.RESET and check.resets == 1


def test_throttle_counts_from_the_last_event() -> None:
    now = [100.0]
    throttle = Throttle(lambda: now[0])
    assert throttle.due('a', 5.0)
    now[0] = 104.9
    assert not throttle.due('a', 5.0)
    now[0] = 105.0
    assert throttle.due('a', 5.0)
