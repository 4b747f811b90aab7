"""Bag player: pure timing, and real playback of a 10 s bag to a separate rclpy subscriber."""

from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from hrn_vo_ros.cli.main import main as hrn_vo
from hrn_vo_ros.core.events.arrays import EventChecksum
from hrn_vo_ros.core.events.sequence import random_sequence
from hrn_vo_ros.errors import ConfigError, DecodeError
from hrn_vo_ros.io import bags, convert, ecd
from hrn_vo_ros.io.playback import play, PlaybackConfig, PlaybackSchedule

ROOT = Path(__file__).resolve().parents[2]
SINK = ROOT / 'test' / 'ros_helpers' / 'event_sink.py'


def test_schedule_maps_bag_time_to_wall_time() -> None:
    s = PlaybackSchedule(5_000_000_000, 100.0, rate=4.0)
    assert s.due(5_000_000_000) == 100.0
    assert s.due(9_000_000_000) == pytest.approx(101.0)
    assert s.bag_time_at(100.5) == 7_000_000_000
    assert PlaybackSchedule(0, 3.0, rate=None).due(10**12) == 3.0


def test_clock_ticks_are_rate_limited_and_monotonic() -> None:
    s = PlaybackSchedule(0, 0.0, rate=1.0, clock_hz=100.0)
    assert s.clock_tick(0, 0.0) == 0
    assert s.clock_tick(1_000_000, 0.001) is None  # within one clock period
    assert s.clock_tick(20_000_000, 0.02) == 20_000_000
    assert s.clock_tick(10_000_000, 0.5) is None  # never backwards
    assert s.clock_tick(20_000_001, 0.0201, force=True) == 20_000_001


def test_play_loop_publishes_on_time_with_a_fake_clock() -> None:
    wall = [100.0]
    log: list[tuple[str, float, object]] = []

    def sleep(dt: float) -> None:
        wall[0] += dt

    records = [('/a', 10**9, b'0'), ('/b', 15 * 10**8, b'1'), ('/a', 15 * 10**8, b'2'),
               ('/a', 3 * 10**9, b'3')]
    sent = play(records, lambda topic, raw: log.append((topic, wall[0], raw)), rate=2.0,
                clock=lambda t: log.append(('clock', wall[0], t)), now=lambda: wall[0],
                sleep=sleep)
    assert sent == {'/a': 3, '/b': 1}
    assert log == [('clock', 100.0, 10**9), ('/a', 100.0, b'0'),
                   ('clock', 100.25, 15 * 10**8), ('/b', 100.25, b'1'), ('/a', 100.25, b'2'),
                   ('clock', 101.0, 3 * 10**9), ('/a', 101.0, b'3')]
    wall[0] = 0.0
    log.clear()
    play(records, lambda topic, raw: log.append((topic, wall[0], raw)), rate=None,
         now=lambda: wall[0], sleep=sleep)
    assert [entry[1] for entry in log] == [0.0] * 4  # max rate: no waiting


def test_config_is_validated() -> None:
    with pytest.raises(ConfigError, match='rate'):
        PlaybackConfig(rate=0.0)


@pytest.fixture(scope='module')
def ten_second_bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, object]]:
    """A 10 s bag: 20 k events/s in 10 ms packets, IMU at 200 Hz, ground truth at 100 Hz."""
    n = 200_000
    seq = random_sequence(np.random.default_rng(5), 10.0, n / 10.0, imu_period_ns=5_000_000,
                          gt_every=2)
    ev = seq.events
    tmp = tmp_path_factory.mktemp('player')
    folder = ecd.write_sequence(tmp / 'seq', seq)
    stats = convert.convert(folder, tmp / 'bag', packet_duration_ms=10.0)
    with bags.open_bag(tmp / 'bag') as reader:
        last_t = reader.end_time - 1  # rosbags' end_time is one past the last record
    c = EventChecksum()
    c.update(ev)
    assert (stats.events, stats.checksum) == (c.count, c.hexdigest())
    return tmp / 'bag', {'packets': stats.packets, 'events': n, 'checksum': c.hexdigest(),
                         'last_t': last_t, 'imu': stats.imu}


def play_to_sink(player_cmd: list[str], expected_packets: int, timeout: float, *,
                 reliable: bool = False,
                 ) -> tuple[dict[str, object], subprocess.CompletedProcess[str]]:
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get('PYTHONPATH')])])}  # this checkout
    sink = subprocess.Popen([sys.executable, str(SINK), '/event_camera/events',
                             str(expected_packets), str(timeout)] + ['reliable'] * reliable,
                            cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert sink.stdout is not None
    line = sink.stdout.readline().strip()
    assert line == 'ready', sink.communicate()[1][-2000:]
    player = subprocess.run(player_cmd, cwd=ROOT, capture_output=True, text=True,
                            timeout=timeout + 30, env=env)
    out, err = sink.communicate(timeout=timeout + 30)
    assert out.strip(), f'sink printed nothing: {err[-2000:]}'
    return json.loads(out.strip().splitlines()[-1]), player


def check_delivery(got: dict[str, object], want: dict[str, object], rate: float) -> None:
    assert got['missing'] == []
    assert (got['packets'], got['events'], got['checksum']) == \
        (want['packets'], want['events'], want['checksum'])
    clock = got['clock']
    assert isinstance(clock, dict) and clock['monotonic'] and clock['last'] == want['last_t']
    duration = 10.0 / rate
    assert clock['n'] >= 0.5 * 100 * duration  # ~100 Hz ticks while playing
    assert got['duration_s'] == pytest.approx(duration, rel=0.25, abs=0.5)


@pytest.mark.ros
def test_cli_plays_every_packet_at_4x_with_clock(
        ten_second_bag: tuple[Path, dict[str, object]]) -> None:
    bag, want = ten_second_bag
    got, player = play_to_sink(
        [sys.executable, '-m', 'hrn_vo_ros.cli.main', 'play', str(bag), '--rate', '4',
         '--clock', '--wait-for-subscribers', '1'], int(want['packets']), timeout=60)  # type: ignore[call-overload]
    assert player.returncode == 0, player.stderr[-2000:]
    assert f"/event_camera/events {want['packets']}" in player.stdout
    assert f"/imu {want['imu']}" in player.stdout
    check_delivery(got, want, 4.0)


@pytest.mark.ros
def test_node_plays_every_packet_in_real_time(
        ten_second_bag: tuple[Path, dict[str, object]]) -> None:
    """The one long test: 10 s of playback at 1x through the bag_player executable."""
    bag, want = ten_second_bag
    got, player = play_to_sink(
        [sys.executable, '-m', 'hrn_vo_ros.nodes.bag_player', '--ros-args', '-p',
         f'bag:={bag}', '-p', 'clock:=true', '-p', 'wait_for_subscribers:=1',
         '-p', 'topics:=[/event_camera/events, /imu]'],
        int(want['packets']), timeout=60)  # type: ignore[call-overload]
    assert player.returncode == 0, player.stderr[-2000:]
    check_delivery(got, want, 1.0)


@pytest.mark.ros
def test_max_rate_is_paced_by_a_slow_reliable_subscriber(
        ten_second_bag: tuple[Path, dict[str, object]]) -> None:
    bag, want = ten_second_bag
    got, player = play_to_sink(
        [sys.executable, '-m', 'hrn_vo_ros.cli.main', 'play', str(bag), '--max-rate',
         '--topics', '/event_camera/events', '--wait-for-subscribers', '1'],
        int(want['packets']), timeout=60, reliable=True)  # type: ignore[call-overload]
    assert player.returncode == 0, player.stderr[-2000:]
    assert got['missing'] == [] and got['checksum'] == want['checksum']
    assert 2.0 <= float(got['duration_s']) < 10.0  # type: ignore[arg-type]  # 1000 x >= 2 ms


@pytest.mark.ros
def test_recorded_qos_and_overrides(ten_second_bag: tuple[Path, dict[str, object]]) -> None:
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

    from hrn_vo_ros.nodes.bag_player import qos_profile

    with bags.open_bag(ten_second_bag[0]) as reader:
        conns = {c.topic: c for c in reader.connections}
    events = qos_profile(conns['/event_camera/events'])
    assert (events.reliability, events.history, events.depth) == \
        (ReliabilityPolicy.BEST_EFFORT, HistoryPolicy.KEEP_LAST, 1000)
    info = qos_profile(conns['/event_camera/camera_info'])
    assert (info.reliability, info.durability) == (ReliabilityPolicy.RELIABLE,
                                                   DurabilityPolicy.TRANSIENT_LOCAL)
    forced = qos_profile(conns['/event_camera/events'], reliable=True, keep_all=True)
    assert (forced.reliability, forced.history) == (ReliabilityPolicy.RELIABLE,
                                                    HistoryPolicy.KEEP_ALL)


@pytest.mark.ros
def test_reliable_option_reaches_reliable_subscribers(
        ten_second_bag: tuple[Path, dict[str, object]]) -> None:
    bag, want = ten_second_bag
    got, player = play_to_sink(
        [sys.executable, '-m', 'hrn_vo_ros.cli.main', 'play', str(bag), '--rate', '20',
         '--reliable', '--topics', '/event_camera/events', '--wait-for-subscribers', '1'],
        int(want['packets']), timeout=60, reliable=True)  # type: ignore[call-overload]
    assert player.returncode == 0, player.stderr[-2000:]
    assert got['missing'] == [] and got['checksum'] == want['checksum']


@pytest.mark.ros
def test_topics_of_unknown_types_are_skipped(tmp_path: Path) -> None:
    import rclpy
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_types_from_msg, get_typestore, Stores

    from hrn_vo_ros.nodes.bag_player import BagPlayer

    ts = get_typestore(Stores.ROS2_JAZZY)
    ts.register(get_types_from_msg('int32 a\n', 'hrn_test_msgs/msg/Foo'))
    with Writer(tmp_path / 'bag', version=9, storage_plugin=StoragePlugin.MCAP) as w:
        foo = w.add_connection('/foo', 'hrn_test_msgs/msg/Foo', typestore=ts)
        imu = w.add_connection('/imu', 'sensor_msgs/msg/Imu', typestore=ts)
        w.write(foo, 1, ts.serialize_cdr(ts.types['hrn_test_msgs/msg/Foo'](a=1),
                                         'hrn_test_msgs/msg/Foo'))
        w.write(imu, 2, bags.imu_cdr_batch(np.array([2]), np.zeros((1, 3)), np.zeros((1, 3)),
                                           frame_id='imu')[0])
    rclpy.init()
    try:
        node = BagPlayer(PlaybackConfig(bag=str(tmp_path / 'bag'), rate=100.0))
        assert node.play() == {'/imu': 1}
        node.destroy_node()
        with pytest.raises(DecodeError, match='hrn_test_msgs'):
            BagPlayer(PlaybackConfig(bag=str(tmp_path / 'bag'), topics=('/foo',)))
    finally:
        rclpy.try_shutdown()


@pytest.mark.ros
def test_player_refuses_bad_bags(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / 'x.partial' / 'x').mkdir(parents=True)
    assert hrn_vo(['play', str(tmp_path / 'x.partial' / 'x')]) == 4
    assert 'unfinished' in capsys.readouterr().err
    assert hrn_vo(['play', str(tmp_path / 'missing')]) == 4
    assert 'does not exist' in capsys.readouterr().err


@pytest.mark.ros
def test_wait_topics_choose_what_the_player_waits_for(
        ten_second_bag: tuple[Path, dict[str, object]]) -> None:
    """By default the player waits for event subscribers only; ``wait_topics`` (e.g. the IMU,
    whose first samples a late subscriber would lose) replaces that list, unknown ones fail."""
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Imu

    from hrn_vo_ros.nodes.bag_player import BagPlayer

    bag = str(ten_second_bag[0])
    rclpy.init()
    try:
        default = BagPlayer(PlaybackConfig(bag=bag, wait_for_subscribers=1, wait_timeout_s=0.3))
        assert default.waited_for == ['/event_camera/events']
        imu_sub = default.create_subscription(Imu, '/imu', lambda _m: None,
                                              qos_profile_sensor_data)   # best effort, as recorded
        assert not default.wait_for_subscribers()          # nobody on the events: times out
        default.destroy_subscription(imu_sub)
        default.destroy_node()
        imu = BagPlayer(PlaybackConfig(bag=bag, wait_for_subscribers=1, wait_timeout_s=5.0,
                                       wait_topics=('/imu',)))
        sub = imu.create_subscription(Imu, '/imu', lambda _m: None, qos_profile_sensor_data)
        assert imu.waited_for == ['/imu'] and imu.wait_for_subscribers()
        imu.destroy_subscription(sub)
        imu.destroy_node()
        with pytest.raises(ConfigError, match='/nope'):
            BagPlayer(PlaybackConfig(bag=bag, wait_topics=('/nope',)))
    finally:
        rclpy.try_shutdown()


@pytest.mark.ros
def test_max_rate_publish_retries_on_back_pressure_then_gives_up() -> None:
    from rclpy._rclpy_pybind11 import RCLError

    from hrn_vo_ros.errors import BagError
    from hrn_vo_ros.io.playback import publish_retrying

    clock = [0.0]
    calls: list[bytes] = []

    def sleep(dt: float) -> None:
        clock[0] += dt

    def busy_twice(raw: bytes) -> None:
        calls.append(raw)
        if len(calls) <= 2:
            raise RCLError('failed to publish: timeout')

    assert publish_retrying(busy_twice, b'x', 1.0, retry_on=RCLError, now=lambda: clock[0],
                            sleep=sleep) == 2
    assert calls == [b'x'] * 3

    def always_busy(raw: bytes) -> None:
        raise RCLError('failed to publish: timeout')

    with pytest.raises(BagError, match='max_rate'):
        publish_retrying(always_busy, b'x', 0.05, retry_on=RCLError, now=lambda: clock[0],
                         sleep=sleep)
