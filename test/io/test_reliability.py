"""Where data enters: each measured failure is refused with a package error naming the input."""

from __future__ import annotations

from pathlib import Path
import shutil
import sqlite3

import numpy as np
import pytest

from hrn_vo_ros.core.evaluation.protocol import EstimateSeries, evaluate
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import random_sequence, Trajectory
from hrn_vo_ros.errors import BagError, DatasetError, DatasetWarning, DecodeError, IntegrityError
from hrn_vo_ros.io import bags, convert, ecd, eventpacket

FIXTURE = Path(__file__).resolve().parents[1] / 'fixtures' / 'seq1s'


def test_mono_time_base_near_int64_overflow_is_refused() -> None:
    raw = eventpacket.encode_mono(EventArray.from_arrays(
        np.array([0, 7]), np.array([1, 2]), np.array([3, 4]), np.array([0, 1])), time_base=0)[1]
    for tb in (2**63, 2**64 - 1, 2**63 - 10):
        with pytest.raises(DecodeError, match='time_base'):
            eventpacket.decode_mono(raw, time_base=tb)
        with pytest.raises(DecodeError, match='time_base'):
            eventpacket.PacketDecoder().decode('mono', raw, time_base=tb)
    ok = eventpacket.decode_mono(raw, time_base=2**63 - 2**32 - 1)
    assert int(ok.t.min()) > 0


def _copy(tmp_path: Path) -> Path:
    dst = tmp_path / 'seq'
    shutil.copytree(FIXTURE, dst)
    return dst


def test_twenty_digit_coordinate_is_a_dataset_error(tmp_path: Path) -> None:
    seq = _copy(tmp_path)
    lines = (seq / 'events.txt').read_text().splitlines()
    lines[3] = lines[3].split()[0] + ' 12345678901234567890 5 1'
    (seq / 'events.txt').write_text('\n'.join(lines) + '\n')
    (seq / 'meta.json').unlink()
    with pytest.raises(DatasetError, match=r'events.txt:4: .*digits'):
        ecd.read_events(seq, sensor_size=(240, 180))


def test_zero_quaternion_and_huge_gyro_are_refused(tmp_path: Path) -> None:
    seq = _copy(tmp_path)
    gt = (seq / 'groundtruth.txt').read_text().splitlines()
    gt[2] = ' '.join(gt[2].split()[:4] + ['0', '0', '0', '0'])
    (seq / 'groundtruth.txt').write_text('\n'.join(gt) + '\n')
    with pytest.raises(DatasetError, match=r'groundtruth.txt:3: quaternion'):
        ecd.read_groundtruth(seq)
    imu = (seq / 'imu.txt').read_text().splitlines()
    imu[1] = ' '.join(imu[1].split()[:4] + ['1e308', '0', '0'])
    (seq / 'imu.txt').write_text('\n'.join(imu) + '\n')
    with pytest.raises(DatasetError, match=r'imu.txt:2: angular rate'):
        ecd.read_imu(seq)


def _gt(n: int = 200) -> Trajectory:
    t = np.arange(n, dtype=np.int64) * 10_000_000
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    return Trajectory(t=t, pos=np.zeros((n, 3)), quat=quat)


def test_evaluate_refuses_zero_quaternions_and_absurd_estimates() -> None:
    gt = _gt()
    est = EstimateSeries(t=gt.t[5:150] + 1, h=np.linspace(0, 1, 145), v=np.zeros(145),
                         r=np.zeros(145))
    bad_q = gt.quat.copy()
    bad_q[7] = 0.0
    with pytest.raises(DatasetError, match='pose 7.*quaternion'):
        evaluate(Trajectory(t=gt.t, pos=gt.pos, quat=bad_q), est, 'rotation')
    huge = EstimateSeries(t=est.t, h=np.full(145, 1e308), v=est.v, r=est.r)
    with pytest.raises(DatasetError, match="column 'h' holds 1e"):
        evaluate(gt, huge, 'rotation')


@pytest.fixture(scope='module')
def converted(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp('bags')
    return {s: (convert.convert(FIXTURE, root / s, storage=s), root / s)[1]
            for s in ('mcap', 'sqlite3')}


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_converted_bag_verifies_with_stored_checksum(storage: str,
                                                     converted: dict[str, Path]) -> None:
    res = bags.verify_bag(converted[storage])
    assert res.checksum == res.stored_checksum == bags.custom_data(
        converted[storage])[bags.CHECKSUM_KEY]
    assert res.events == int(bags.custom_data(converted[storage])[bags.COUNT_KEY])
    if storage == 'mcap':
        assert res.chunks_crc_checked >= 1
        scan = bags.scan_mcap(next(converted[storage].glob('*.mcap')))
        assert scan.data_crc_stored == scan.data_crc and scan.summary_crc_stored
    assert res.notes == ()


def _storage_file(bag: Path) -> Path:
    return next(p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3'))


def test_flipped_bytes_in_an_mcap_bag_are_caught(tmp_path: Path,
                                                 converted: dict[str, Path]) -> None:
    bag = tmp_path / 'bad'
    shutil.copytree(converted['mcap'], bag)
    f = _storage_file(bag)
    raw = bytearray(f.read_bytes())
    mid = len(raw) // 2
    raw[mid:mid + 256] = bytes(b ^ 0xFF for b in raw[mid:mid + 256])
    f.write_bytes(raw)
    with pytest.raises(BagError, match=r'/event_camera/events.*chunk at byte \d+.*CRC'):
        for _ in bags.iter_bag_events(bag):
            pass
    with pytest.raises(IntegrityError, match=r'chunk at byte \d+ .*fails its CRC'):
        bags.verify_bag(bag)


def test_flipped_event_payload_in_a_sqlite_bag_is_caught(tmp_path: Path,
                                                         converted: dict[str, Path]) -> None:
    bag = tmp_path / 'bad'
    shutil.copytree(converted['sqlite3'], bag)
    con = sqlite3.connect(_storage_file(bag))
    rid, data = con.execute("SELECT m.id, m.data FROM messages m JOIN topics t ON "
                            "t.id = m.topic_id WHERE t.name = '/event_camera/events' "
                            'ORDER BY m.id LIMIT 1 OFFSET 100').fetchone()
    data = bytearray(data)
    data[-3] ^= 0xA5  # the high byte of the last event's x
    con.execute('UPDATE messages SET data = ? WHERE id = ?', (bytes(data), rid))
    con.commit()
    con.close()
    with pytest.raises(DecodeError, match=r'/event_camera/events: message 100 .*(sensor|before)'):
        for _ in bags.iter_bag_events(bag):
            pass
    with pytest.raises(DecodeError, match='message 100'):
        bags.verify_bag(bag)


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_edited_message_count_is_refused(tmp_path: Path, storage: str,
                                         converted: dict[str, Path]) -> None:
    bag = tmp_path / 'bad'
    shutil.copytree(converted[storage], bag)
    meta = (bag / 'metadata.yaml').read_text()
    n = bags.verify_bag(converted[storage]).counts['/imu']
    assert f'message_count: {n}\n' in meta
    (bag / 'metadata.yaml').write_text(meta.replace(f'message_count: {n}\n',
                                                    f'message_count: {n + 5}\n', 1))
    with pytest.raises(IntegrityError, match=r'metadata.yaml: topic /imu has message_count'):
        bags.open_bag(bag)


def test_absurd_bag_time_span_is_refused(tmp_path: Path) -> None:
    dst = tmp_path / 'span'
    with bags.BagWriter(dst) as w:
        conn = w.add_topic('/x', 'std_msgs/msg/String', bags.RELIABLE_QOS)
        T = w.ts.types
        for t in (0, 63 * 365 * 86400 * 1_000_000_000):
            w.write_msg(conn, t, T['std_msgs/msg/String'](data='a'))
    with pytest.raises(BagError, match=r'span of .* days'):
        bags.open_bag(dst)


def test_missing_calib_warns(tmp_path: Path) -> None:
    seq = tmp_path / 'seq'
    ecd.write_sequence(seq, random_sequence(np.random.default_rng(1), 0.05, 5000))
    (seq / 'calib.txt').unlink()
    with pytest.warns(DatasetWarning, match='no calib.txt'):
        stats = convert.convert(seq, tmp_path / 'bag')
    assert stats.camera_info == 0 and 'camera_info' in stats.warnings[0]
