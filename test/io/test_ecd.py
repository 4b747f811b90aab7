"""Event Camera Dataset text layout: exact round trips, streaming, zip, and every bad input."""

from __future__ import annotations

from pathlib import Path
import zipfile

import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray, EventChecksum
from hrn_vo_ros.core.events.sequence import CameraCalibration, ImuData, Sequence, Trajectory
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io import ecd
from hrn_vo_ros.io.ecd import eventparse, writer


def make_sequence(rng: np.random.Generator, n: int = 5000, *, width: int = 240,
                  height: int = 180) -> Sequence:
    t = np.sort(rng.integers(0, 3_000_000_000, n))
    t[:3] = [0, 1, 1]  # the very first stamp and a tie
    t[-1] = 12_345_678_901_234  # seconds with 5 digits, all 9 decimals significant
    ev = EventArray.from_arrays(t, rng.integers(0, width, n), rng.integers(0, height, n),
                                rng.integers(0, 2, n))
    ti = np.arange(0, 3_000_000_000, 1_000_000, dtype=np.int64) + 7
    imu = ImuData(t=ti, acc=rng.normal(size=(ti.size, 3)), gyro=rng.normal(size=(ti.size, 3)))
    tg = ti[::5]
    q = rng.normal(size=(tg.size, 4))
    gt = Trajectory(t=tg, pos=rng.normal(size=(tg.size, 3)),
                    quat=q / np.linalg.norm(q, axis=1, keepdims=True))
    calib = CameraCalibration(width=width, height=height, fx=199.092366542, fy=198.82882047,
                              cx=132.192071378, cy=110.712660011,
                              dist=(-0.368436311798, 0.150947243557, -0.000296130534385,
                                    -0.000759431726241, 0.0))
    return Sequence(events=ev, calib=calib, imu=imu, groundtruth=gt)


def checksum(batches: list[EventArray] | EventArray) -> tuple[int, str]:
    c = EventChecksum()
    for b in batches if isinstance(batches, list) else [batches]:
        c.update(b)
    return c.count, c.hexdigest()


def test_round_trip_is_exact(tmp_path: Path, rng: np.random.Generator) -> None:
    seq = make_sequence(rng)
    ecd.write_sequence(tmp_path / 'seq', seq)
    back = ecd.read_sequence(tmp_path / 'seq')
    assert checksum(back.events) == checksum(seq.events)
    assert back.calib == seq.calib
    assert back.imu is not None and seq.imu is not None
    np.testing.assert_array_equal(back.imu.t, seq.imu.t)
    np.testing.assert_array_equal(back.imu.acc, seq.imu.acc)
    np.testing.assert_array_equal(back.imu.gyro, seq.imu.gyro)
    assert back.groundtruth is not None and seq.groundtruth is not None
    np.testing.assert_array_equal(back.groundtruth.t, seq.groundtruth.t)
    np.testing.assert_array_equal(back.groundtruth.quat, seq.groundtruth.quat)
    assert ecd.event_count(tmp_path / 'seq') == len(seq.events)
    line = (tmp_path / 'seq' / 'events.txt').read_text().splitlines()[-1]
    assert line.startswith('12345.678901234 ')


def test_streaming_batches_and_zip(tmp_path: Path, rng: np.random.Generator,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    seq = make_sequence(rng, n=20000, width=346, height=260)
    monkeypatch.setattr(eventparse, '_parse_slow', None)  # our files take the vectorised path
    folder = ecd.write_sequence(tmp_path / 'seq', seq)
    batches = list(ecd.iter_events(folder, chunk_events=3000))
    assert len(batches) >= 7 and max(len(b) for b in batches) <= 3000
    assert checksum(batches) == checksum(seq.events)
    assert ecd.read_sensor_size(folder) == (346, 260)
    for prefix in ('', 'shapes_rotation/'):  # members at the root or under one folder
        zpath = tmp_path / f'seq{len(prefix)}.zip'
        with zipfile.ZipFile(zpath, 'w', zipfile.ZIP_DEFLATED) as z:
            for p in folder.iterdir():
                z.write(p, prefix + p.name)
        assert checksum(list(ecd.iter_events(zpath, chunk_events=5000))) == \
            checksum(seq.events)
        assert ecd.read_calib(zpath) == seq.calib
        assert len(ecd.read_imu(zpath)) == len(seq.imu or [])


def write_plain(folder: Path, events: str, *, calib: str = '200 200 120 90 0 0 0 0 0\n',
                imu: str | None = None) -> Path:
    """A folder as the real dataset has it: no meta.json."""
    folder.mkdir()
    (folder / 'events.txt').write_text(events)
    (folder / 'calib.txt').write_text(calib)
    if imu is not None:
        (folder / 'imu.txt').write_text(imu)
    return folder


def test_plain_dataset_folder_defaults_to_davis240(tmp_path: Path) -> None:
    folder = write_plain(tmp_path / 'ecd', '0.000000000 33 39 1\n0.000011000 239 179 0\n')
    assert ecd.read_sensor_size(folder) == (240, 180)
    ev = ecd.read_events(folder)
    assert ev.t.tolist() == [0, 11000] and ev.x.tolist() == [33, 239]
    assert ev.p.tolist() == [1, 0]
    assert ecd.event_count(folder) is None
    assert ecd.estimate_event_count(folder) == 2
    assert ecd.read_calib(folder).width == 240


def test_other_layouts_parse_line_by_line(tmp_path: Path) -> None:
    text = '# comment\n1.5\t3  4 1\r\n\n2.000001 5 6 0\r\n3 7 8 1'  # no final newline
    ev = ecd.read_events(write_plain(tmp_path / 'x', text))
    assert ev.t.tolist() == [1_500_000_000, 2_000_001_000, 3_000_000_000]
    assert ev.x.tolist() == [3, 5, 7] and ev.y.tolist() == [4, 6, 8]


@pytest.mark.parametrize(('eol', 't0'), [('\n', 0), ('\r\n', 0), ('\n', 99_999_990),
                                         ('\n', 1_468_939_993)])
def test_six_decimals_fast_path(tmp_path: Path, eol: str, t0: int,
                                monkeypatch: pytest.MonkeyPatch) -> None:
    lines = ''.join(f'{t0 + i}.{i:06d} {i % 240} {i % 180} {i % 2}{eol}' for i in range(1000))
    monkeypatch.setattr(eventparse, '_parse_slow', None)  # must not be needed
    ev = ecd.read_events(write_plain(tmp_path / 'x', lines))
    assert ev.t.tolist() == [(t0 + i) * 1_000_000_000 + i * 1000 for i in range(1000)]
    assert ev.p.tolist() == [i % 2 for i in range(1000)]


GOOD = ''.join(f'0.{i:09d} {i % 240} {i % 180} 1\n' for i in range(1, 2001))


@pytest.mark.parametrize(('events', 'line', 'words'), [
    (GOOD + '0.000003000 1 2 1 7\n', 2001, 'expected 4 columns'),
    (GOOD + '0.000003000 1 2\n', 2001, 'expected 4 columns'),
    (GOOD + '0.000003000 1 garbage 1\n', 2001, 'malformed'),
    (GOOD + '\x00\x00\x00\x00\n', 2001, 'expected 4 columns'),
    (GOOD + '-0.000003000 1 2 1\n', 2001, 'non-negative'),
    (GOOD.replace('0.000001000 40 100 1', '0.000001000 40 100 2'), 1000, 'polarity 2'),
    (GOOD.replace('0.000001500 60 60 1', '0.000001500 240 60 1'), 1500, 'outside the 240x180'),
    (GOOD.replace('0.000001500 60 60 1', '0.000001500 60 -1 1'), 1500, 'outside the 240x180'),
    (GOOD.replace('0.000001500 60 60 1', '0.000000500 60 60 1'), 1500, 'sorted by time'),
    (GOOD + '0.0000', 2001, 'truncated'),
    (GOOD + '9999999999.000000000 1 2 1\n', 2001, 'too large'),
])
def test_bad_event_lines_name_file_and_line(tmp_path: Path, events: str, line: int,
                                            words: str) -> None:
    folder = write_plain(tmp_path / 'x', events)
    with pytest.raises(DatasetError, match=words) as info:
        for _ in ecd.iter_events(folder, chunk_events=700):  # errors in later chunks too
            pass
    assert info.value.line == line
    assert info.value.path == folder / 'events.txt'
    assert f'events.txt:{line}:' in str(info.value)


def test_truncated_at_line_boundary_detected_by_meta(tmp_path: Path,
                                                     rng: np.random.Generator) -> None:
    folder = ecd.write_sequence(tmp_path / 'seq', make_sequence(rng))
    path = folder / 'events.txt'
    text = path.read_text()
    path.write_text(text[:text.index('\n', len(text) // 2) + 1])
    with pytest.raises(DatasetError, match='truncated'):
        ecd.read_events(folder)


def test_corrupt_zip(tmp_path: Path, rng: np.random.Generator) -> None:
    folder = ecd.write_sequence(tmp_path / 'seq', make_sequence(rng))
    zpath = tmp_path / 'seq.zip'
    with zipfile.ZipFile(zpath, 'w', zipfile.ZIP_DEFLATED) as z:
        for p in folder.iterdir():
            z.write(p, p.name)
    data = zpath.read_bytes()
    cut = tmp_path / 'cut.zip'
    cut.write_bytes(data[:len(data) // 2])
    with pytest.raises(DatasetError):
        ecd.read_events(cut)
    with zipfile.ZipFile(zpath) as z:
        info = z.getinfo('events.txt')
    mid = info.header_offset + 30 + len('events.txt') + info.compress_size // 2
    flipped = bytearray(data)
    flipped[mid:mid + 64] = bytes(64)  # corrupt the compressed events.txt data
    bad = tmp_path / 'bad.zip'
    bad.write_bytes(bytes(flipped))
    with pytest.raises(DatasetError):
        ecd.read_events(bad)


def test_missing_and_malformed_side_files(tmp_path: Path) -> None:
    folder = write_plain(tmp_path / 'x', GOOD, imu='0.1 1 2 3 4 5 6\n0.2 1 2 3 4 5\n')
    with pytest.raises(DatasetError, match='missing groundtruth.txt'):
        ecd.read_groundtruth(folder)
    with pytest.raises(DatasetError, match='expected 7 columns') as info:
        ecd.read_imu(folder)
    assert info.value.line == 2
    (folder / 'calib.txt').write_text('200 200 abc 90 0 0 0 0 0\n')
    with pytest.raises(DatasetError, match='malformed calibration'):
        ecd.read_calib(folder)
    with pytest.raises(DatasetError, match='does not exist'):
        ecd.read_events(tmp_path / 'nothing')
    seq = ecd.read_sequence(write_plain(tmp_path / 'y', GOOD))
    assert seq.imu is None and seq.groundtruth is None and len(seq.events) == 2000


def test_sensor_size_from_meta_is_enforced(tmp_path: Path, rng: np.random.Generator) -> None:
    folder = ecd.write_sequence(tmp_path / 'seq', make_sequence(rng, width=240, height=180))
    meta = (folder / 'meta.json').read_text().replace('"width": 240', '"width": 100')
    (folder / 'meta.json').write_text(meta)
    with pytest.raises(DatasetError, match='outside the 100x180 sensor'):
        ecd.read_events(folder)


def test_writer_refuses_overwrite_and_leaves_nothing_when_interrupted(
        tmp_path: Path, rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch) -> None:
    seq = make_sequence(rng)
    ecd.write_sequence(tmp_path / 'seq', seq)
    with pytest.raises(DatasetError, match='already exists'):
        ecd.write_sequence(tmp_path / 'seq', seq)

    def boom(ev: EventArray) -> bytes:
        raise KeyboardInterrupt

    monkeypatch.setattr(writer, 'format_events', boom)  # where write_sequence looks it up
    with pytest.raises(KeyboardInterrupt):
        ecd.write_sequence(tmp_path / 'other', seq)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['seq']


def test_partial_folders_are_refused(tmp_path: Path) -> None:
    folder = write_plain(tmp_path / '.seq.partial-abc', GOOD)
    with pytest.raises(DatasetError, match='unfinished write'):
        ecd.read_events(folder)


def test_writer_rejects_invalid_sequences(tmp_path: Path) -> None:
    calib = CameraCalibration(width=10, height=10, fx=1.0, fy=1.0, cx=5.0, cy=5.0)
    ev = EventArray.from_arrays(np.array([5, 3]), np.array([1, 2]), np.array([1, 2]),
                                np.array([0, 1]))
    with pytest.raises(DatasetError, match='sorted'):
        ecd.write_sequence(tmp_path / 'a', Sequence(events=ev, calib=calib))
    ev = EventArray.from_arrays(np.array([1, 3]), np.array([1, 12]), np.array([1, 2]),
                                np.array([0, 1]))
    with pytest.raises(DatasetError, match='outside'):
        ecd.write_sequence(tmp_path / 'a', Sequence(events=ev, calib=calib))
    assert list(tmp_path.iterdir()) == []


def test_format_events_matches_python_formatting(rng: np.random.Generator) -> None:
    t = np.sort(rng.integers(0, 10**14, 500))
    x, y, p = rng.integers(0, 65535, 500), rng.integers(0, 40000, 500), rng.integers(0, 2, 500)
    expected = ''.join(f'{a // 10**9}.{a % 10**9:09d} {b} {c} {d}\n'
                       for a, b, c, d in zip(t, x, y, p, strict=True))
    assert ecd.format_events(EventArray.from_arrays(t, x, y, p)).decode() == expected
