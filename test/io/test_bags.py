"""ROS 2 bag helpers: typestore, CDR of EventPacket, crash-safe writer, refusing half bags."""

from __future__ import annotations

from pathlib import Path
import shutil

import numpy as np
import pytest
from rosbags.interfaces import QosReliability
import yaml

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import BagError
from hrn_vo_ros.io import bags, eventpacket

EVENT_PACKET_HASH = 'RIHS01_d6fa176260b1f37e5a40845305315e150a0f18191241eb64f407442aa29844aa'
DVS_HASH = 'RIHS01_0ea4aa5f4670adab1336550158b2e3c9bf60fe515a284c4215ed605bd559c995'
DRIVER_BAGS = Path(__file__).resolve().parents[2].parent / 'shared' / 'data' / 'driver_bags'


def test_typestore_has_official_hashes() -> None:
    ts = bags.typestore()
    assert ts.hash_rihs01(bags.EVENT_PACKET) == EVENT_PACKET_HASH
    assert ts.hash_rihs01(bags.DVS_EVENT_ARRAY) == DVS_HASH


@pytest.mark.parametrize('frame_id', ['', 'x', 'event_camera', 'abcdefgh'])
def test_event_packet_cdr_is_byte_identical_to_rosbags(frame_id: str,
                                                       rng: np.random.Generator) -> None:
    ev = EventArray.from_arrays(np.sort(rng.integers(0, 10**6, 37)), rng.integers(0, 240, 37),
                                rng.integers(0, 180, 37), rng.integers(0, 2, 37))
    time_base, payload = eventpacket.encode_mono(ev)
    ts = bags.typestore()
    T = ts.types
    msg = T[bags.EVENT_PACKET](
        header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=12, nanosec=345), frame_id=frame_id), height=180, width=240, seq=7,
        time_base=time_base, encoding='mono', is_bigendian=False, events=payload)
    ours = bags.event_packet_cdr(stamp_ns=12_000_000_345, frame_id=frame_id, height=180,
                                 width=240, seq=7, time_base=time_base, encoding='mono',
                                 is_bigendian=False, payload=payload)
    assert ours == bytes(ts.serialize_cdr(msg, bags.EVENT_PACKET))


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_writer_records_qos_and_renames_when_done(tmp_path: Path, storage: bags.Storage) -> None:
    dst = tmp_path / 'bag'
    with bags.BagWriter(dst, storage=storage) as w:
        conn = w.add_topic('/event_camera/events', bags.EVENT_PACKET, bags.EVENTS_QOS)
        raw = bags.event_packet_cdr(stamp_ns=1, frame_id='f', height=1, width=1, seq=0,
                                    time_base=1, encoding='mono', is_bigendian=False,
                                    payload=b'')
        w.write(conn, 5, raw)
        assert not dst.exists() and (tmp_path / 'bag.partial').is_dir()
    assert sorted(p.name for p in tmp_path.iterdir()) == ['bag']
    with bags.open_bag(dst) as reader:
        (c,) = reader.connections
        assert bags.qos_profiles(c)[0].reliability == QosReliability.BEST_EFFORT
        assert [(m.topic, m.t_ns) for m in bags.iter_messages(reader)] == \
            [('/event_camera/events', 5)]
    with pytest.raises(BagError, match='exists already'):
        bags.BagWriter(dst)


def test_interrupted_write_leaves_nothing(tmp_path: Path) -> None:
    dst = tmp_path / 'bag'
    with pytest.raises(KeyboardInterrupt), bags.BagWriter(dst) as w:
        w.add_topic('/x', bags.EVENT_PACKET, bags.EVENTS_QOS)
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_readers_refuse_partial_missing_and_corrupt_bags(tmp_path: Path) -> None:
    half = tmp_path / 'a.partial' / 'a'
    half.mkdir(parents=True)
    with pytest.raises(BagError, match='unfinished'), bags.open_bag(half):
        pass
    with pytest.raises(BagError, match=r'convert again.*`hrn-vo recover .*a\.partial`'):
        bags.open_bag(half)
    with pytest.raises(BagError, match='does not exist'), bags.open_bag(tmp_path / 'nothing'):
        pass
    (tmp_path / 'empty').mkdir()
    with pytest.raises(BagError, match='metadata.yaml'), bags.open_bag(tmp_path / 'empty'):
        pass
    dst = tmp_path / 'bag'
    with bags.BagWriter(dst) as w:
        conn = w.add_topic('/imu', 'sensor_msgs/msg/Imu', bags.SENSOR_QOS)
        for i in range(100):
            w.write(conn, i, bytes(400))
    (mcap,) = dst.glob('*.mcap')
    data = mcap.read_bytes()
    mcap.write_bytes(data[:len(data) // 2])
    with pytest.raises(BagError), bags.open_bag(dst) as reader:
        list(bags.iter_messages(reader))


@pytest.mark.parametrize('frame_id', ['', 'imu', 'world', 'a_longer_frame'])
def test_batch_imu_and_pose_cdr_are_byte_identical_to_rosbags(
        frame_id: str, rng: np.random.Generator) -> None:
    ts = bags.typestore()
    T = ts.types
    t = np.array([0, 1_500_000_001, 2**40 + 7])
    acc, gyro = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    pos, quat = rng.normal(size=(3, 3)), rng.normal(size=(3, 4))
    imu = bags.imu_cdr_batch(t, acc, gyro, frame_id=frame_id)
    poses = bags.pose_cdr_batch(t, pos, quat, frame_id=frame_id)
    q_cov = np.zeros(9)
    q_cov[0] = -1.0
    for i in range(3):
        header = T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=int(t[i]) // 10**9, nanosec=int(t[i]) % 10**9), frame_id=frame_id)
        V = T['geometry_msgs/msg/Vector3']
        msg = T['sensor_msgs/msg/Imu'](
            header=header, orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0,
                                                                         w=1.0),
            orientation_covariance=q_cov, angular_velocity=V(*gyro[i]),
            angular_velocity_covariance=np.zeros(9), linear_acceleration=V(*acc[i]),
            linear_acceleration_covariance=np.zeros(9))
        assert imu[i] == bytes(ts.serialize_cdr(msg, 'sensor_msgs/msg/Imu'))
        pose = T['geometry_msgs/msg/PoseStamped'](header=header, pose=T['geometry_msgs/msg/Pose'](
            position=T['geometry_msgs/msg/Point'](*pos[i]),
            orientation=T['geometry_msgs/msg/Quaternion'](*quat[i])))
        assert poses[i] == bytes(ts.serialize_cdr(pose, 'geometry_msgs/msg/PoseStamped'))


# ------------------------------------------------------------------ metadata versions 5 to 9

def older_metadata(bag: Path, version: int) -> None:
    """Rewrite a version 9 bag's metadata.yaml as rosbag2 of ``version`` wrote it.

    Fields newer than ``version`` are removed and ``storage_identifier`` is left empty, as the
    libcaer driver's test recording has it (version 5).
    """
    doc = yaml.safe_load((bag / 'metadata.yaml').read_text())
    info = doc['rosbag2_bagfile_information']
    info['version'] = version
    info['storage_identifier'] = ''
    for topic in info['topics_with_message_count']:
        meta = topic['topic_metadata']  # QoS before version 9: one YAML string
        meta['offered_qos_profiles'] = yaml.safe_dump(meta['offered_qos_profiles'])
        if version < 7:
            del meta['type_description_hash']
    if version < 8:
        del info['ros_distro']
    if version < 6:
        del info['custom_data']
        info['files'] = []
    (bag / 'metadata.yaml').write_text(yaml.safe_dump(doc))


def small_bag(dst: Path, storage: bags.Storage) -> None:
    with bags.BagWriter(dst, storage=storage) as w:
        conn = w.add_topic('/event_camera/events', bags.EVENT_PACKET, bags.EVENTS_QOS)
        for i in range(3):
            w.write(conn, 10 + i, bags.event_packet_cdr(
                stamp_ns=i, frame_id='cam', height=1, width=1, seq=i, time_base=i,
                encoding='mono', is_bigendian=False, payload=b''))


@pytest.mark.parametrize('version', [5, 6, 7, 8, 9])
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_open_bag_reads_metadata_versions_5_to_9(tmp_path: Path, storage: bags.Storage,
                                                 version: int) -> None:
    dst = tmp_path / 'bag'
    small_bag(dst, storage)
    if version < 9:
        older_metadata(dst, version)
    assert bags.bag_storage(dst) == storage
    with bags.open_bag(dst) as reader:
        (conn,) = reader.connections
        assert conn.msgtype == bags.EVENT_PACKET
        assert bags.qos_profiles(conn)[0].reliability == QosReliability.BEST_EFFORT
        assert [m.t_ns for m in bags.iter_messages(reader)] == [10, 11, 12]


def test_open_bag_refuses_unknown_versions_and_storages(tmp_path: Path) -> None:
    dst = tmp_path / 'bag'
    small_bag(dst, 'mcap')
    meta = dst / 'metadata.yaml'
    text = meta.read_text()
    meta.write_text(text.replace('version: 9', 'version: 10'))
    with pytest.raises(BagError, match='version 10; this reader opens versions 5 to 9'):
        bags.open_bag(dst)
    meta.write_text(text.replace('storage_identifier: mcap', "storage_identifier: ''")
                    .replace('- bag.mcap', '- bag.bin'))
    (dst / 'bag.mcap').rename(dst / 'bag.bin')
    with pytest.raises(BagError, match='cannot tell the storage'):
        bags.open_bag(dst)
    meta.write_text(':\n  - [')
    with pytest.raises(BagError, match='unreadable bag metadata'):
        bags.open_bag(dst)


def test_open_bag_reads_the_libcaer_driver_recording() -> None:
    path = DRIVER_BAGS / 'test_events_2'
    if not path.is_dir():
        pytest.skip(f'the real driver recordings are not here ({path} is absent: they live '
                    'in ../shared/data/driver_bags beside the repository)')
    # metadata version 5 with an empty storage_identifier: the .mcap file names the storage
    assert bags.bag_storage(path) == 'mcap'
    with bags.open_bag(path) as reader:
        (conn,) = reader.connections
        assert (conn.topic, conn.msgtype) == ('/event_camera/events', bags.EVENT_PACKET)
        assert reader.message_count == 100
        assert bags.qos_profiles(conn)[0].depth == 1000
        assert sum(1 for _ in bags.iter_messages(reader)) == 100


def _payload(i: int) -> bytes:
    return np.random.default_rng(i).integers(0, 256, 8000, dtype=np.uint8).tobytes()


def _snapshot_after_flush(tmp_path: Path, flushed: int, pending: int) -> Path:
    """``snap.partial``: what a writer killed after ``flushed`` messages (then ``flushed`` +
    ``pending`` written, the rest still in its open chunk) leaves on disk."""
    snap = tmp_path / 'snap.partial'
    with bags.BagWriter(tmp_path / 'bag') as w:
        conn = w.add_topic('/imu', 'sensor_msgs/msg/Imu', bags.RELIABLE_QOS)
        for i in range(flushed):
            w.write(conn, 1_000 + i, _payload(i))
        w.flush()
        for i in range(flushed, flushed + pending):
            w.write(conn, 1_000 + i, _payload(i))
        shutil.copytree(tmp_path / 'bag.partial', snap)
        (inner,) = snap.iterdir()
        inner.rename(snap / 'snap')
        (snap / 'snap' / 'bag.mcap').rename(snap / 'snap' / 'snap.mcap')
    return snap


def test_recover_salvages_every_flushed_message(tmp_path: Path) -> None:
    snap = _snapshot_after_flush(tmp_path, 300, 40)   # 2.4 MB: 2 full chunks + the flush
    with pytest.raises(BagError, match='unfinished'):
        bags.open_bag(snap)
    res = bags.recover_bag(snap)
    assert res.dst == tmp_path / 'snap' and res.chunks == 3
    assert res.counts == {'/imu': 300} and (res.start_ns, res.end_ns) == (1_000, 1_299)
    assert res.dropped_bytes == 0 and snap.is_dir()          # the source is left as it was
    assert not (tmp_path / 'snap.partial.recovering').exists()
    ver = bags.verify_bag(res.dst)
    assert ver.counts == {'/imu': 300} and ver.chunks_crc_checked == 3
    with bags.open_bag(res.dst) as reader:
        msgs = list(bags.iter_messages(reader))
        assert bags.qos_profiles(reader.connections[0])[0].reliability == \
            QosReliability.RELIABLE
    assert [m.t_ns for m in msgs] == list(range(1_000, 1_300))
    assert all(bytes(m.raw) == _payload(i) for i, m in enumerate(msgs))
    assert bags.custom_data(res.dst)[bags.RECOVERED_KEY] == str(snap)
    with pytest.raises(BagError, match='exists already'):
        bags.recover_bag(snap)


def test_recover_stops_at_a_chunk_cut_off_or_damaged(tmp_path: Path) -> None:
    snap = _snapshot_after_flush(tmp_path, 300, 0)
    (mcap,) = snap.rglob('*.mcap')
    data = mcap.read_bytes()
    first = data.index(bytes([0x06]), 8)           # the first chunk record, after the header
    mcap.write_bytes(data + data[first:first + 5000])  # a chunk whose writing was cut off
    res = bags.recover_bag(mcap, tmp_path / 'out')
    assert res.counts == {'/imu': 300} and res.dropped_bytes == 5000
    assert 'cut off' in res.stop_reason
    mcap.write_bytes(data[:first + 100])            # not even the first chunk is complete
    with pytest.raises(BagError, match='no complete chunk'):
        bags.recover_bag(snap, tmp_path / 'out2')
    assert not (tmp_path / 'out2').exists() and not (tmp_path / 'out2.partial').exists()
    db = tmp_path / 'lite.partial' / 'lite'
    db.mkdir(parents=True)
    (db / 'lite.db3').write_bytes(b'')
    with pytest.raises(BagError, match='sqlite3'):
        bags.recover_bag(tmp_path / 'lite.partial')
