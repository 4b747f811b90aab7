"""Dataset -> ROS 2 bag: every input form, exact events, packets, bad inputs through the CLI."""

from __future__ import annotations

import json
from pathlib import Path
import shutil

import numpy as np
import pytest

from hrn_vo_ros.cli.main import main as hrn_vo
from hrn_vo_ros.core.events.arrays import EventArray, EventChecksum
from hrn_vo_ros.core.events.sequence import random_sequence
from hrn_vo_ros.errors import ConfigError, DecodeError
from hrn_vo_ros.io import bags, convert, ecd, eventpacket, npy, ros1bag

FIXTURES = Path(__file__).resolve().parents[1] / 'fixtures'
EXPECTED = json.loads((FIXTURES / 'expected.json').read_text())


def digest(batches: object) -> tuple[int, str]:
    c = EventChecksum()
    for b in batches:  # type: ignore[attr-defined]
        c.update(b)
    return c.count, c.hexdigest()


def test_fixtures_read_exactly_in_every_form() -> None:
    want = (EXPECTED['events'], EXPECTED['checksum'])
    assert digest(ecd.iter_events(FIXTURES / 'seq1s')) == want
    assert digest(ecd.iter_events(FIXTURES / 'seq1s.zip')) == want
    assert digest(npy.iter_npy_events(FIXTURES / 'seq1s_npy' / 'events.npy')) == want
    with ros1bag.Ros1Dataset(FIXTURES / 'seq1s.bag') as ds:
        assert digest(ds.events()) == (EXPECTED['events'], EXPECTED['ros1_checksum'])
        imu, gt = ds.imu(), ds.groundtruth()
        assert imu is not None and len(imu) == EXPECTED['imu']
        assert gt is not None and len(gt) == EXPECTED['groundtruth']
    assert len(ecd.read_imu(FIXTURES / 'seq1s.zip')) == EXPECTED['imu']
    assert len(npy.read_trajectory(FIXTURES / 'seq1s_npy' / 'trajectory.txt')) == \
        EXPECTED['groundtruth']


@pytest.mark.parametrize(('src', 'checksum_key'), [
    ('seq1s', 'checksum'), ('seq1s.zip', 'checksum'), ('seq1s.bag', 'ros1_checksum'),
    ('seq1s_npy', 'checksum')])
def test_every_form_converts_bit_exactly(tmp_path: Path, src: str, checksum_key: str) -> None:
    dst = tmp_path / 'bag'
    stats = convert.convert(FIXTURES / src, dst, packet_duration_ms=10.0)
    want = (EXPECTED['events'], EXPECTED[checksum_key])
    assert (stats.events, stats.checksum) == want
    assert digest(bags.iter_bag_events(dst)) == want
    with bags.open_bag(dst) as reader:
        topics = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        qos = {c.topic: bags.qos_profiles(c)[0] for c in reader.connections}
        times = [m.t_ns for m in bags.iter_messages(reader)]
    assert topics[convert.EVENTS_TOPIC] == (bags.EVENT_PACKET, stats.packets)
    assert topics[convert.IMU_TOPIC] == ('sensor_msgs/msg/Imu', EXPECTED['imu'])
    assert topics[convert.POSE_TOPIC] == ('geometry_msgs/msg/PoseStamped',
                                          EXPECTED['groundtruth'])
    assert topics[convert.CAMERA_INFO_TOPIC] == ('sensor_msgs/msg/CameraInfo', 1)
    assert qos[convert.EVENTS_TOPIC].reliability.name == 'BEST_EFFORT'
    assert times == sorted(times)
    offset = EXPECTED['ros1_offset_ns'] if src.endswith('.bag') else 0
    assert times[0] <= EXPECTED['first_t_ns'] + offset
    assert stats.packets <= 101  # 10 ms packets over 1 s


def test_packets_carry_the_sensor_clock(tmp_path: Path) -> None:
    dst = tmp_path / 'bag'
    convert.convert(FIXTURES / 'seq1s', dst, events_per_packet=300, storage='sqlite3')
    ts = bags.typestore()
    with bags.open_bag(dst) as reader:
        packets = [(m.t_ns, ts.deserialize_cdr(m.raw, m.msgtype))
                   for m in bags.iter_messages(reader, [convert.EVENTS_TOPIC])]
        info = next(ts.deserialize_cdr(m.raw, m.msgtype)
                    for m in bags.iter_messages(reader, [convert.CAMERA_INFO_TOPIC]))
    calib = ecd.read_calib(FIXTURES / 'seq1s')
    assert (info.width, info.height, info.k[0], info.k[2], tuple(info.d)) == \
        (calib.width, calib.height, calib.fx, calib.cx, calib.dist)
    assert [len(p.events) // 8 for _, p in packets] == [300] * 6 + [EXPECTED['events'] - 1800]
    for i, (t_bag, p) in enumerate(packets):
        ev = eventpacket.decode_mono(p.events, time_base=p.time_base)
        assert p.seq == i and p.encoding == 'mono' and (p.width, p.height) == (240, 180)
        assert p.header.stamp.sec * 10**9 + p.header.stamp.nanosec == p.time_base == ev.t[0]
        assert t_bag == ev.t[-1]


def test_packet_splitter_keeps_every_event(rng: np.random.Generator) -> None:
    t = np.sort(rng.integers(0, 20 * 10**9, 20000))
    t[5000:] += 30 * 10**9  # a 30 s gap: count-mode packets must still span < 4.29 s
    ev = EventArray.from_arrays(t, np.zeros(t.size), np.zeros(t.size), np.zeros(t.size))
    cuts = np.sort(rng.choice(np.arange(1, t.size), 50, replace=False))
    for kwargs in ({'events_per_packet': 64}, {'duration_ns': 7_000_000},
                   {'duration_ns': eventpacket.MONO_MAX_DT}):
        splitter = convert.PacketSplitter(**kwargs)
        packets = [p for part in np.split(np.arange(t.size), cuts)
                   for p in splitter.push(ev[part])] + splitter.flush()
        assert digest(packets) == digest([ev])
        assert all(int(p.t[-1] - p.t[0]) <= eventpacket.MONO_MAX_DT for p in packets)
        if 'duration_ns' in kwargs:
            bins = [set(((p.t - t[0]) // kwargs['duration_ns']).tolist()) for p in packets]
            assert all(len(b) == 1 for b in bins)
            assert len({b.pop() for b in bins}) == len(packets)
        else:
            sizes = [len(p) for p in packets]
            crossings = int((t[-1] - t[0]) // 4_000_000_000) + 1  # 4 s grid lines cut too
            assert max(sizes) == 64 and sum(s != 64 for s in sizes) <= 2 * crossings + 1


def test_random_sequence_stamps(rng: np.random.Generator) -> None:
    us = random_sequence(rng, 0.1, 20_000, stamps='us').events.t
    mixed = random_sequence(rng, 0.1, 20_000, stamps='mixed').events.t
    assert np.all(us % 1000 == 0) and np.all(np.diff(us) >= 0)
    assert 0 < np.mean(mixed % 1000 != 0) < 0.5 and np.all(np.diff(mixed) >= 0)
    with pytest.raises(ConfigError, match='stamps'):
        random_sequence(rng, 0.1, 1000, stamps='ms')


def test_ten_second_sequence_round_trips_bit_exactly(tmp_path: Path,
                                                     rng: np.random.Generator) -> None:
    """Acceptance: text -> bag -> decoded events, and ROS 1 bag -> ROS 2 bag, bit-exact."""
    seq = random_sequence(rng, 10.0, 60_000, stamps='mixed')  # some stamps off whole us
    want = digest([seq.events])
    folder = ecd.write_sequence(tmp_path / 'seq', seq)
    assert hrn_vo(['convert', str(folder), str(tmp_path / 'from_text')]) == 0
    assert digest(bags.iter_bag_events(tmp_path / 'from_text')) == want
    ros1bag.write_ros1_bag(tmp_path / 'seq.bag', seq, events_per_message=20_000)
    assert hrn_vo(['convert', str(tmp_path / 'seq.bag'), str(tmp_path / 'from_ros1'),
                   '--storage', 'sqlite3', '--events-per-packet', '5000']) == 0
    assert digest(bags.iter_bag_events(tmp_path / 'from_ros1')) == want


def test_ros2_evt3_bag_repacketises_to_mono(tmp_path: Path, rng: np.random.Generator) -> None:
    n = 3000
    ev = EventArray.from_arrays(np.sort(rng.integers(0, 3 * 10**9, n)) // 1000 * 1000,
                                rng.integers(0, 640, n), rng.integers(0, 480, n),
                                rng.integers(0, 2, n))
    stream = eventpacket.encode_evt3(ev)
    with bags.BagWriter(tmp_path / 'live') as w:
        conn = w.add_topic('/event_camera/events', bags.EVENT_PACKET, bags.EVENTS_QOS)
        for i, part in enumerate(np.array_split(stream.view('<u2'), 7)):
            w.write(conn, i, bags.event_packet_cdr(
                stamp_ns=i, frame_id='cam', height=480, width=640, seq=i, time_base=0,
                encoding='evt3', is_bigendian=False, payload=part.view(np.uint8)))
    stats = convert.convert(tmp_path / 'live', tmp_path / 'mono')
    assert (stats.events, stats.source_kind) == (n, 'ros2')
    assert digest(bags.iter_bag_events(tmp_path / 'mono')) == digest([ev])


def test_ros2_dvs_bag_converts(tmp_path: Path) -> None:
    ts = bags.typestore()
    T = ts.types
    ev = ecd.read_events(FIXTURES / 'seq1s')[:300]
    with bags.BagWriter(tmp_path / 'dvs') as w:
        conn = w.add_topic('/dvs/events', bags.DVS_EVENT_ARRAY, bags.EVENTS_QOS)
        for i in range(0, 300, 100):
            part = ev[i:i + 100]
            events = [T['dvs_msgs/msg/Event'](x=int(x), y=int(y), ts=T[
                'builtin_interfaces/msg/Time'](sec=int(t) // 10**9, nanosec=int(t) % 10**9),
                polarity=bool(p)) for t, x, y, p in zip(part.t, part.x, part.y, part.p,
                                                        strict=True)]
            msg = T[bags.DVS_EVENT_ARRAY](header=T['std_msgs/msg/Header'](
                stamp=T['builtin_interfaces/msg/Time'](sec=0, nanosec=i), frame_id='dvs'),
                height=180, width=240, events=events)
            w.write(conn, i, ts.serialize_cdr(msg, bags.DVS_EVENT_ARRAY))
    stats = convert.convert(tmp_path / 'dvs', tmp_path / 'mono')
    assert (stats.events, stats.source_kind) == (300, 'ros2')
    assert digest(bags.iter_bag_events(tmp_path / 'mono')) == digest([ev])


def write_bad(tmp_path: Path, kind: str) -> tuple[list[str], str]:
    """A bad input and the words its error message must contain."""
    folder = tmp_path / 'seq'
    shutil.copytree(FIXTURES / 'seq1s', folder)
    events = folder / 'events.txt'
    text = events.read_text()
    if kind == 'truncated':
        events.write_text(text[:len(text) // 2])
        return [str(folder)], 'truncated'
    if kind == 'garbage':
        lines = text.splitlines(keepends=True)
        lines[1000] = 'this is not an event\n'
        events.write_text(''.join(lines))
        return [str(folder)], 'events.txt:1001:'
    if kind == 'sensor':
        return [str(folder), '--sensor-size', '100x100'], 'outside the 100x100 sensor'
    if kind == 'corrupt_bag':
        data = (FIXTURES / 'seq1s.bag').read_bytes()
        bad = tmp_path / 'bad.bag'
        bad.write_bytes(data[:len(data) * 2 // 3])
        return [str(bad)], 'bad.bag'
    if kind == 'unknown_encoding':
        with bags.BagWriter(tmp_path / 'caer') as w:
            conn = w.add_topic('/event_camera/events', bags.EVENT_PACKET, bags.EVENTS_QOS)
            w.write(conn, 1, bags.event_packet_cdr(
                stamp_ns=1, frame_id='cam', height=180, width=240, seq=0, time_base=0,
                encoding='trigger_only', is_bigendian=False, payload=bytes(16)))
        return [str(tmp_path / 'caer')], "unknown EventPacket encoding 'trigger_only'"
    raise AssertionError(kind)


@pytest.mark.parametrize('kind', ['truncated', 'garbage', 'sensor', 'corrupt_bag',
                                  'unknown_encoding'])
def test_bad_input_fails_cleanly_and_leaves_nothing(tmp_path: Path, kind: str,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    args, words = write_bad(tmp_path, kind)
    before = set(tmp_path.iterdir())
    dst = tmp_path / 'out'
    code = hrn_vo(['convert', *args, str(dst)])
    err = capsys.readouterr().err
    assert code != 0 and 'hrn-vo convert: error:' in err and words in err, err
    assert set(tmp_path.iterdir()) == before  # neither out nor out.partial


def test_convert_refuses_to_overwrite(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / 'out').mkdir()
    assert hrn_vo(['convert', str(FIXTURES / 'seq1s'), str(tmp_path / 'out')]) == 4
    assert 'exists already' in capsys.readouterr().err
    (tmp_path / 'out2.partial').mkdir()
    assert hrn_vo(['convert', str(FIXTURES / 'seq1s'), str(tmp_path / 'out2')]) == 4
    assert 'interrupted' in capsys.readouterr().err


def test_unknown_encoding_while_reading_a_bag(tmp_path: Path) -> None:
    write_bad(tmp_path, 'unknown_encoding')
    with pytest.raises(DecodeError, match='trigger_only'):
        list(bags.iter_bag_events(tmp_path / 'caer'))


def test_interrupted_conversion_leaves_nothing(tmp_path: Path) -> None:
    def interrupt(n: int) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        convert.convert(FIXTURES / 'seq1s', tmp_path / 'out', progress=interrupt)
    assert list(tmp_path.iterdir()) == []


def test_events_only_folder_converts(tmp_path: Path) -> None:
    folder = tmp_path / 'bare'
    folder.mkdir()
    shutil.copy(FIXTURES / 'seq1s' / 'events.txt', folder / 'events.txt')
    stats = convert.convert(folder, tmp_path / 'bag')
    assert (stats.events, stats.checksum) == (EXPECTED['events'], EXPECTED['checksum'])
    assert (stats.imu, stats.poses, stats.camera_info) == (0, 0, 0)
