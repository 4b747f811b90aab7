"""The packetizer stream (core/events/stream.py) on hand-made packets, without ROS."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from hrn_vo_ros.core.clock import ClockConfig, Recent
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.packet_config import CalibrationConfig, paper_framing
from hrn_vo_ros.core.events.sequence import CameraCalibration
from hrn_vo_ros.core.events.stream import packet_problem, PacketStream, StreamOutput
from hrn_vo_ros.errors import HrnVoError

MS = 1_000_000
S = 1_000_000_000
T0 = 1_760_000_000 * S          # header clock (ROS time)
CFG = paper_framing(events_per_frame=100, sensor_width=40, sensor_height=30, downsample=1.0)


def packet(t0_ns: int, n: int = 100, *, w: int = 40, h: int = 30,
           seed: int = 0) -> EventArray:
    rng = np.random.default_rng(seed)
    return EventArray.from_arrays(t0_ns + np.arange(n) * 10_000, rng.integers(0, w, n),
                                  rng.integers(0, h, n), np.ones(n))


def no_state() -> EventArray | None:
    return None


def push(stream: PacketStream, sensor_ns: int, header_ns: int | None = None, *,
         seq: int = 0, size: tuple[int, int] = (0, 0), ev: EventArray | None = None,
         wait: int = 10**9) -> StreamOutput:
    ev = packet(sensor_ns) if ev is None else ev
    return stream.push(T0 + sensor_ns if header_ns is None else header_ns, ev, seq=seq,
                       size=size, redecode=no_state, wait_events=wait)


def kinds(out: StreamOutput) -> list[tuple[str, str]]:
    return [(n.level, n.kind) for n in out.notes]


def test_frames_are_stamped_in_the_header_clock_and_counted() -> None:
    counts: Counter[str] = Counter()
    stream = PacketStream(CFG, counts=counts)
    out = push(stream, 5 * S)
    assert out.accepted and len(out.frames) == 1
    stamp, image = out.frames[0]
    assert image.shape == (30, 40)
    # the frame time is inside the packet, mapped by the offset T0
    assert T0 + 5 * S <= stamp <= T0 + 5 * S + 99 * 10_000
    assert counts['events_in'] == 100 and counts['frames_out'] == 1
    assert stream.clock.offset_ns == T0


def test_a_sensor_clock_restart_resets_the_mapping_and_drops_the_partial_frame() -> None:
    counts: Counter[str] = Counter()
    stream = PacketStream(CFG, counts=counts)
    push(stream, 5 * S, ev=packet(5 * S, 150))                 # leaves 50 pending
    out = push(stream, 1 * S, T0 + 5 * S + 10 * MS, seq=7)     # sensor went back 4 s
    assert kinds(out) == [('warn', 'clock_reset')] and out.notes[0].throttled
    assert 'sensor_backwards' in out.notes[0].text and 'seq 7' in out.notes[0].text
    assert counts['clock_resets_sensor_backwards'] == 1
    assert counts['dropped_on_clock_reset'] == 50
    assert len(out.frames) == 1 and stream.last_reset.within(1.0)
    assert stream.states(10.0) == [('warn', 'event clock reset (sensor_backwards)')]


def test_after_a_reset_a_stateful_packet_is_decoded_again() -> None:
    stream = PacketStream(CFG)
    push(stream, 5 * S)
    again = packet(2 * S, seed=1)
    calls: list[int] = []

    def redecode() -> EventArray | None:
        calls.append(1)
        return again

    out = stream.push(T0 + 5 * S + 10 * MS, packet(30 * S), seq=1, size=(0, 0),
                      redecode=redecode, wait_events=10**9)
    assert calls == [1] and out.accepted
    assert stream.clock.offset_ns == T0 + 5 * S + 10 * MS - 2 * S    # the new times count
    empty = stream.push(T0 + 6 * S, packet(90 * S), seq=2, size=(0, 0),
                        redecode=EventArray.empty, wait_events=10**9)
    assert not empty.accepted and stream.counts['dropped_on_decoder_reset'] == 0


def test_redecode_errors_are_decode_rejects() -> None:
    stream = PacketStream(CFG)
    push(stream, 5 * S)

    def broken() -> EventArray | None:
        raise ValueError('corrupt')

    out = stream.push(T0 + 5 * S, packet(1 * S), seq=1, size=(0, 0), redecode=broken,
                      wait_events=10**9)
    assert ('reject', 'decode') in kinds(out) and not out.accepted


def test_small_steps_back_and_bad_packets_are_rejected_with_their_kind() -> None:
    stream = PacketStream(CFG)
    push(stream, 5 * S)
    out = push(stream, 5 * S + 500_000)               # starts before the last one ended
    assert kinds(out) == [('reject', 'time_backwards')] and not out.accepted
    out = push(stream, 6 * S, ev=EventArray.empty(), seq=3)
    assert kinds(out) == [('reject', 'empty')] and out.notes[0].text == 'seq 3, 0 events'
    out = push(stream, 6 * S, ev=packet(6 * S, w=41))
    assert kinds(out)[-1] == ('reject', 'out_of_sensor')


def test_a_config_size_mismatch_is_counted_and_noted_but_the_config_wins() -> None:
    stream = PacketStream(CFG)
    out = push(stream, 5 * S, size=(640, 480))
    assert kinds(out) == [('warn', 'sensor_size_mismatch')] and out.notes[0].throttled
    assert stream.counts['sensor_size_mismatch'] == 1 and len(out.frames) == 1
    assert kinds(push(stream, 6 * S, size=(40, 30))) == []


def test_sensor_size_from_messages_waits_then_restarts_on_a_change() -> None:
    stream = PacketStream(CFG, sensor_size='messages')
    assert stream.packetizer is None
    assert stream.states(10.0) == [('warn', 'waiting for the sensor size (0 events held)')]
    out = push(stream, 5 * S, size=(40, 30), ev=packet(5 * S, 150))
    assert kinds(out) == [('info', 'sensor_size')] and len(out.frames) == 1
    assert 'sensor size 40x30 from the event packets: frames are 40x30' in out.notes[0].text
    out = push(stream, 6 * S, size=(50, 30))
    assert 'changed: packetizer restarted' in out.notes[0].text
    assert stream.counts['dropped_on_sensor_size'] == 50
    assert stream.packetizer is not None and stream.packetizer.cfg.sensor_width == 50
    out = push(stream, 7 * S, size=(70000, 30))
    assert kinds(out) == [('reject', 'sensor_size')]


RECT = paper_framing(events_per_frame=100, sensor_width=40, sensor_height=30,
                     downsample=1.0, rectify='pinhole')
CALIB = CameraCalibration(width=40, height=30, fx=30.0, fy=30.0, cx=20.0, cy=15.0)


def test_events_are_held_until_camera_info_then_binned_first() -> None:
    stream = PacketStream(RECT)
    assert stream.needs_camera_info and stream.packetizer is None
    for k in range(3):
        out = push(stream, 5 * S + k * 10 * MS, wait=250)
        assert out.accepted and out.frames == []
    assert stream.held == 200 and stream.counts['dropped_waiting_for_camera_info'] == 100
    assert kinds(out) == [('warn', 'waiting')]
    assert '100 events dropped so far' in out.notes[0].text
    assert stream.states(10.0)[0] == ('warn', 'waiting for camera_info (200 events held)')
    out = stream.calibrate(CALIB)
    assert kinds(out) == [('info', 'camera_info')] and '200 held events go first' in \
        out.notes[0].text
    assert len(out.frames) == 2 and stream.held == 0 and stream.states(10.0) == []


def test_a_calibration_no_packetizer_takes_changes_nothing() -> None:
    stream = PacketStream(RECT)
    with pytest.raises(HrnVoError):
        stream.calibrate(CameraCalibration(width=40, height=30, fx=30.0, fy=30.0, cx=20.0,
                                           cy=15.0, dist=(0.0, 0.0, 0.0, 0.0, 1e9)))
    assert stream.calib is None and stream.packetizer is None


def test_known_calibration_needs_no_camera_info() -> None:
    known = paper_framing(events_per_frame=100, sensor_width=40, sensor_height=30,
                          downsample=1.0, rectify='pinhole',
                          calib=CalibrationConfig(fx=30.0, fy=30.0, cx=20.0, cy=15.0))
    assert PacketStream(known).packetizer is not None


def test_reconfigure_restarts_only_a_running_packetizer() -> None:
    stream = PacketStream(CFG)
    push(stream, 5 * S, ev=packet(5 * S, 150))
    new = paper_framing(events_per_frame=30, sensor_width=40, sensor_height=30,
                        downsample=1.0)
    assert stream.reconfigure(new)
    assert stream.packetizer is not None and stream.packetizer.pending == 0
    waiting = PacketStream(RECT)
    assert not waiting.reconfigure(new) and waiting.cfg is new


def test_diagnostic_values_and_the_reset_window() -> None:
    now = [100.0]
    stream = PacketStream(CFG, clock=ClockConfig(), recent=Recent(lambda: now[0]))
    push(stream, 5 * S, ev=packet(5 * S, 150))
    values = dict(stream.diagnostic_values('2.0', 3))
    assert values['pending_events'] == 50 and values['frames_subscribers'] == 3
    assert values['sensor_size'] == '40x30' and values['frame_size'] == '40x30'
    assert values['clock_offset_ns'] == T0 and values['waiting_for_camera_info'] is False
    push(stream, 1 * S, T0 + 5 * S + 10 * MS)
    assert stream.states(10.0) != []
    now[0] += 10.5
    assert stream.states(10.0) == []


def test_packet_problem_kinds() -> None:
    ev = packet(0)
    assert packet_problem(ev, CFG, None) is None
    assert packet_problem(ev, CFG, int(ev.t[0]) + 1) == 'time_backwards'
    unsorted = EventArray.from_arrays(np.array([2, 1]), np.array([0, 0]), np.array([0, 0]),
                                      np.array([1, 1]))
    assert packet_problem(unsorted, CFG, None) == 'time_backwards'


def test_the_start_up_line_says_what_the_stream_does() -> None:
    """Packet size, sizes, rectification and its wait, QoS and the rate cap (2000 x 1500 events
    per frame and second: 3 M events/s)."""
    capped = paper_framing(events_per_frame=2000, sensor_width=240, sensor_height=180,
                           downsample=2.5, max_frame_hz=1500.0)
    assert PacketStream(capped).describe(events_reliable=False, camera_info_topic='/c') == (
        '2000 events per frame, 240x180 -> 96x72, rectify none, events best effort, above 3 M '
        'events/s an even share binned (max_frame_hz)')
    text = PacketStream(RECT, sensor_size='messages').describe(events_reliable=True,
                                                               camera_info_topic='/cam/info')
    assert text == (f'{RECT.events_per_frame} events per frame, sensor size from the event '
                    f'packets, rectify {RECT.rectify} (no calib.* parameters: events are held '
                    'until a camera_info arrives on /cam/info), events reliable')


def test_packet_bounds_and_equal_timestamps() -> None:
    """Equal timestamps inside a packet and a packet starting at the previous one's last
    event are fine; y == sensor_height is outside wherever it sits in the packet."""
    ev = EventArray.from_arrays(np.array([5, 5, 5, 7]), np.array([1, 2, 3, 4]),
                                np.array([0, 29, 1, 2]), np.ones(4))
    assert packet_problem(ev, CFG, None) is None
    assert packet_problem(ev, CFG, 5) is None
    assert packet_problem(ev, CFG, 6) == 'time_backwards'
    tall = EventArray.from_arrays(np.array([5, 6]), np.array([1, 2]), np.array([30, 0]),
                                  np.ones(2))
    assert packet_problem(tall, CFG, None) == 'out_of_sensor'


def test_a_packet_overlapping_the_last_event_of_the_previous_is_dropped() -> None:
    """The clock keeps each packet's last event: the next one must not start before it."""
    stream = PacketStream(CFG)
    assert push(stream, 5 * S).accepted                       # events 5 s .. 5 s + 990 us
    out = push(stream, 5 * S + 985_000)                       # starts 5 us before that
    assert kinds(out) == [('reject', 'time_backwards')]
    assert push(stream, 5 * S + 990_000).accepted             # at it: fine


def test_non_square_sensor_from_messages_and_calibration() -> None:
    """A 40x30 sensor known from the packets stays 40x30 in the packetizer built on the
    calibration; a calibration before any packet gives the sensor size; zero sizes say
    nothing; a later other size drops the calibration that no longer fits."""
    stream = PacketStream(RECT, sensor_size='messages')
    push(stream, 5 * S, size=(40, 30))
    stream.calibrate(CALIB)
    assert stream.packetizer is not None
    assert (stream.packetizer.cfg.sensor_width, stream.packetizer.cfg.sensor_height) == (40, 30)
    first = PacketStream(RECT, sensor_size='messages')
    first.calibrate(CALIB)
    assert first.sensor == (40, 30)
    fixed = PacketStream(RECT)
    fixed.calibrate(CALIB)
    assert fixed.sensor is None
    assert kinds(push(PacketStream(CFG, sensor_size='messages'), 5 * S, size=(0, 30))) == []
    text = push(PacketStream(CFG, sensor_size='messages'), 5 * S, size=(40, 30)).notes[0].text
    assert '(downsample 1);' in text and 'needs downsample 0.4167 here, or 0: auto' in text
    assert stream.reconfigure(paper_framing(events_per_frame=30, sensor_width=40,
                                            sensor_height=30, downsample=1.0,
                                            rectify='pinhole'))
    assert stream.packetizer is not None and stream.packetizer.cfg.calib.fx == 30.0  # kept
    out = push(stream, 6 * S, size=(50, 30))
    assert ('warn', 'camera_info_size') in kinds(out) and stream.calib is None


def test_held_events_up_to_the_limit_and_diagnostics_before_any_packetizer() -> None:
    stream = PacketStream(RECT)
    for k in range(2):
        push(stream, 5 * S + k * 10 * MS, wait=200)
    assert stream.held == 200 and stream.counts['dropped_waiting_for_camera_info'] == 0
    values = dict(stream.diagnostic_values('0.0', 0))
    assert values['pending_events'] == 0 and values['events_outside_frame'] == 0
    assert values['frames_by_time'] == 0 and values['events_capped'] == 0
    assert values['events_denoised'] == 0 and values['noisy_threshold'] is False
