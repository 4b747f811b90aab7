"""Fuzz every decoder and reader where data enters: valid result or a package error, nothing else.

Targets: the EventPacket codecs (mono, evt3, libcaer_cmp, libcaer, dispatch), legacy dvs
messages (ROS 1 and CDR), the Event Camera Dataset text files, ROS 1 bags, ROS 2 bags (MCAP and
sqlite3, mutated bytes of a small bag made in a temporary folder), the YAML config loader and
NumPy event files. Each target runs ``HRN_FUZZ_SECONDS`` (see ``fuzzlib``).
"""

from __future__ import annotations

from collections.abc import Iterator
import io
from pathlib import Path
import shutil
import tempfile

from fuzzlib import inputs, outcome, ROUND, run_for, seeds
from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import random_sequence
from hrn_vo_ros.errors import HrnVoError
from hrn_vo_ros.io import bags, convert, ecd, eventpacket, npy, ros1bag
from hrn_vo_ros.io.codecs.common import INT64_MAX

TIME_BASES = st.one_of(st.integers(0, 2**64 - 1), st.integers(2**63 - 2**33, 2**63 + 2**33),
                       st.just(0), st.integers(0, 10**18))
ROOT = Path(__file__).resolve().parents[2]


def _valid_events(ev: EventArray) -> None:
    """Invariants of any decoded batch: equal lengths, the promised dtypes, int64-safe times."""
    assert ev.t.dtype == np.int64 and ev.x.dtype == np.uint16 and ev.y.dtype == np.uint16
    assert ev.t.shape == ev.x.shape == ev.y.shape == ev.p.shape
    if len(ev):
        assert int(ev.p.max()) <= 1


@pytest.fixture(scope='module')
def workdir() -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix='hrn_fuzz_') as d:
        yield Path(d)


# ------------------------------------------------------------------------------------ codecs

def test_fuzz_mono() -> None:
    corpus = seeds('mono')

    @ROUND
    @given(inputs(corpus), TIME_BASES, st.booleans())
    def one(payload: bytes, time_base: int, big: bool) -> None:
        res = outcome(eventpacket.decode_mono, payload, time_base=time_base, is_bigendian=big)
        if isinstance(res, EventArray):
            _valid_events(res)
            assert len(res) == len(payload) // 8
            assert len(res) == 0 or (int(res.t.min()) >= time_base
                                     and int(res.t.max()) <= INT64_MAX)
        elif time_base < 2**63 - 2**32 and len(payload) % 8 == 0:
            raise AssertionError(f'a valid mono packet was refused: {res}')

    run_for(one)


def _stream(decode_one: object, packets: list[bytes]) -> None:
    for p in packets:
        res = outcome(decode_one, p)  # type: ignore[arg-type]
        if isinstance(res, HrnVoError):
            continue
        ev = res[0] if isinstance(res, tuple) else res
        _valid_events(ev)


def test_fuzz_evt3() -> None:
    corpus = seeds('evt3')

    @ROUND
    @given(st.lists(inputs(corpus), min_size=1, max_size=4), st.booleans(),
           st.sampled_from([None, 240, 1280]))
    def one(packets: list[bytes], big: bool, width: int | None) -> None:
        dec = eventpacket.Evt3Decoder(width=width, height=width and 720)
        _stream(lambda p: dec.decode_all(p, is_bigendian=big), packets)

    run_for(one)


def test_fuzz_libcaer_cmp() -> None:
    corpus = seeds('libcaer_cmp')

    @ROUND
    @given(st.lists(inputs(corpus), min_size=1, max_size=4), TIME_BASES, st.booleans())
    def one(packets: list[bytes], time_base: int, big: bool) -> None:
        dec = eventpacket.LibcaerCmpDecoder(width=346, height=260)
        _stream(lambda p: dec.decode(p, time_base=time_base, is_bigendian=big), packets)

    run_for(one)


def test_fuzz_libcaer() -> None:
    corpus = seeds('libcaer')

    @ROUND
    @given(inputs(corpus), TIME_BASES, st.booleans())
    def one(payload: bytes, time_base: int, big: bool) -> None:
        res = outcome(eventpacket.decode_libcaer, payload, time_base=time_base,
                      is_bigendian=big)
        if isinstance(res, EventArray):
            _valid_events(res)
            assert len(res) == 0 or int(res.t.min()) >= 0

    run_for(one)


def test_fuzz_packet_dispatch() -> None:
    corpus = seeds('mono') + seeds('evt3') + seeds('libcaer_cmp') + seeds('libcaer')

    @ROUND
    @given(st.lists(st.tuples(st.sampled_from([*eventpacket.ENCODINGS, 'bogus', '']),
                              inputs(corpus), TIME_BASES), min_size=1, max_size=4))
    def one(packets: list[tuple[str, bytes, int]]) -> None:
        dec = eventpacket.PacketDecoder(width=240, height=180)
        for enc, payload, tb in packets:
            res = outcome(dec.decode_all, enc, payload, time_base=tb)
            if not isinstance(res, HrnVoError):
                _valid_events(res[0])

    run_for(one)


def test_fuzz_dvs() -> None:
    ros1, cdr = seeds('dvs_ros1'), seeds('dvs_cdr')

    @ROUND
    @given(inputs(ros1), inputs(cdr))
    def one(a: bytes, b: bytes) -> None:
        for fn, raw in ((eventpacket.decode_dvs_ros1, a), (eventpacket.decode_dvs_cdr, b)):
            res = outcome(fn, raw)
            if not isinstance(res, HrnVoError):
                _valid_events(res.events)

    run_for(one)


# ------------------------------------------------------------------------------------ ECD text

def test_fuzz_ecd_text(workdir: Path) -> None:
    folder = workdir / 'ecd'
    folder.mkdir()
    corpora = {name: seeds(f'ecd_{key}') for name, key in (
        (ecd.EVENTS_FILE, 'events'), (ecd.IMU_FILE, 'imu'), (ecd.GROUNDTRUTH_FILE, 'groundtruth'),
        (ecd.CALIB_FILE, 'calib'))}

    @ROUND
    @given(inputs(corpora[ecd.EVENTS_FILE]), inputs(corpora[ecd.IMU_FILE]),
           inputs(corpora[ecd.GROUNDTRUTH_FILE]), inputs(corpora[ecd.CALIB_FILE]))
    def one(events: bytes, imu: bytes, gt: bytes, calib: bytes) -> None:
        for name, data in ((ecd.EVENTS_FILE, events), (ecd.IMU_FILE, imu),
                           (ecd.GROUNDTRUTH_FILE, gt), (ecd.CALIB_FILE, calib)):
            (folder / name).write_bytes(data)
        res = outcome(lambda: list(ecd.iter_events(folder, sensor_size=(240, 180))))
        if isinstance(res, list):
            for ev in res:
                _valid_events(ev)
                assert len(ev) == 0 or (int(ev.x.max()) < 240 and int(ev.y.max()) < 180)
        imu_res = outcome(ecd.read_imu, folder)
        if not isinstance(imu_res, HrnVoError):
            assert np.all(np.isfinite(imu_res.gyro)) and np.all(np.isfinite(imu_res.acc))
        gt_res = outcome(ecd.read_groundtruth, folder)
        if not isinstance(gt_res, HrnVoError) and len(gt_res):
            assert np.all(np.abs(np.linalg.norm(gt_res.quat, axis=1) - 1) <= 0.1)
        outcome(ecd.read_calib, folder)

    run_for(one)


# ------------------------------------------------------------------------------------ ROS 1 bag

def test_fuzz_ros1_bag(workdir: Path) -> None:
    corpus = seeds('ros1bag')
    path = workdir / 'fuzz.bag'

    @ROUND
    @given(inputs(corpus, max_size=512))
    def one(data: bytes) -> None:
        path.write_bytes(data)

        def read() -> None:
            with ros1bag.Ros1Dataset(path) as ds:
                for ev in ds.events():
                    _valid_events(ev)
                ds.imu()
                ds.groundtruth()
                ds.calib()
                ds.sensor_size()

        outcome(read)

    run_for(one)


# ------------------------------------------------------------------------------------ ROS 2 bag

@pytest.fixture(scope='module')
def small_bags(workdir: Path) -> dict[str, Path]:
    """A small converted bag of each storage (a few packets, IMU, poses, camera info)."""
    seq = random_sequence(np.random.default_rng(3), 0.02, 20_000)
    src = workdir / 'seq'
    ecd.write_sequence(src, seq)
    out = {}
    for storage in ('mcap', 'sqlite3'):
        dst = workdir / f'bag_{storage}'
        convert.convert(src, dst, storage=storage, packet_duration_ms=5.0)
        out[storage] = dst
    return out


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_fuzz_ros2_bag(storage: str, small_bags: dict[str, Path], workdir: Path) -> None:
    bag = small_bags[storage]
    f = next(p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3'))
    original = f.read_bytes()
    meta = (bag / 'metadata.yaml').read_bytes()
    target = workdir / f'mut_{storage}'

    @ROUND
    @given(inputs([original], max_size=64), st.booleans())
    def one(data: bytes, mutate_meta: bool) -> None:
        shutil.rmtree(target, ignore_errors=True)
        target.mkdir()
        (target / f.name).write_bytes(data)
        m = meta
        if mutate_meta:
            m = meta.replace(b'message_count: 499', b'message_count: 498')
        (target / 'metadata.yaml').write_bytes(m)
        res = outcome(lambda: sum(len(ev) for ev in bags.iter_bag_events(target)))
        verdict = outcome(bags.verify_bag, target)
        if data == original and m == meta:
            assert not isinstance(verdict, HrnVoError), verdict
        if not isinstance(verdict, HrnVoError):
            assert verdict.checksum == verdict.stored_checksum
            assert not isinstance(res, HrnVoError)

    run_for(one)


# ------------------------------------------------------------------------------------ YAML

def test_fuzz_yaml_config(workdir: Path) -> None:
    from hrn_vo_ros.io.yamlconfig import load_configs

    corpus = seeds('yaml')
    path = workdir / 'params.yaml'

    @ROUND
    @given(inputs(corpus))
    def one(data: bytes) -> None:
        path.write_bytes(data)
        outcome(load_configs, path)

    run_for(one)


# ------------------------------------------------------------------------------------ NumPy

def test_fuzz_npy(workdir: Path) -> None:
    corpus_npy, corpus_npz = seeds('npy'), seeds('npz')

    @ROUND
    @given(inputs(corpus_npy), inputs(corpus_npz), st.sampled_from(['s', 'ms', 'us', 'ns']))
    def one(a: bytes, b: bytes, unit: npy.TimeUnit) -> None:
        for name, data in (('e.npy', a), ('e.npz', b)):
            p = workdir / name
            p.write_bytes(data)
            res = outcome(lambda p=p: list(npy.iter_npy_events(p, time_unit=unit,
                                                                sensor_size=(240, 180))))
            if isinstance(res, list):
                for ev in res:
                    _valid_events(ev)
            outcome(npy.npy_event_count, p)

    run_for(one)


def test_corpus_seeds_are_valid_inputs() -> None:
    """The seeds themselves decode (so that the mutations start from meaningful inputs)."""
    for raw in seeds('mono'):
        assert len(eventpacket.decode_mono(raw, time_base=5))
    for raw in seeds('evt3'):
        assert len(eventpacket.Evt3Decoder().decode(raw))
    for raw in seeds('dvs_ros1'):
        assert len(eventpacket.decode_dvs_ros1(raw).events)
    for raw in seeds('dvs_cdr'):
        assert len(eventpacket.decode_dvs_cdr(raw).events)
    assert [len(np.load(io.BytesIO(raw))) for raw in seeds('npy')] == [30, 30]
