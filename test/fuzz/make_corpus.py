"""Write the committed seed corpus of the fuzz targets (``corpus/<target>/``).

Run from the repository: ``scripts/run.sh python test/fuzz/make_corpus.py``. Deterministic: a
second run rewrites the same bytes.
"""

from __future__ import annotations

import io
from pathlib import Path
import shutil
import sys

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import random_sequence
from hrn_vo_ros.io import bags, eventpacket, ros1bag

CORPUS = Path(__file__).resolve().parent / 'corpus'
ROOT = Path(__file__).resolve().parents[2]


def _events(rng: np.random.Generator, n: int) -> EventArray:
    return EventArray.from_arrays(np.sort(rng.integers(0, 3_000_000, n)), rng.integers(0, 240, n),
                                  rng.integers(0, 180, n), rng.integers(0, 2, n))


def _put(target: str, name: str, data: bytes) -> None:
    folder = CORPUS / target
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)


def _cmp_words(words: list[tuple[int, int]]) -> bytes:
    return np.array([c << 12 | v for c, v in words], '<u2').tobytes()


def main() -> None:
    shutil.rmtree(CORPUS, ignore_errors=True)
    rng = np.random.default_rng(7)
    for i, n in enumerate((1, 5, 40)):
        ev = _events(rng, n)
        _put('mono', f'mono_{i}.bin', eventpacket.encode_mono(ev)[1].tobytes())
        _put('evt3', f'evt3_{i}.bin', eventpacket.encode_evt3(ev).tobytes())
        _put('evt3', f'evt3_vec_{i}.bin', eventpacket.encode_evt3(ev, vectors=True).tobytes())
        rec = np.zeros(n, [('data', '<u4'), ('ts', '<i4')])
        rec['data'] = (ev.x.astype(np.uint32) << 17) | (ev.y.astype(np.uint32) << 2) | (
            ev.p.astype(np.uint32) << 1)
        rec['ts'] = ev.t // 1000
        _put('libcaer', f'libcaer_{i}.bin', rec.tobytes())
        dvs = ros1bag.encode_dvs_ros1(ev, stamp_ns=int(ev.t[0]), seq=i, frame_id='cam',
                                      width=240, height=180)
        _put('dvs_ros1', f'dvs_{i}.bin', bytes(dvs))
        ts = bags.typestore()
        T = ts.types
        msg = T[bags.DVS_EVENT_ARRAY](
            header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
                sec=1, nanosec=2), frame_id='cam'), height=180, width=240,
            events=[T['dvs_msgs/msg/Event'](x=int(ev.x[k]), y=int(ev.y[k]),
                                            ts=T['builtin_interfaces/msg/Time'](
                                                sec=int(ev.t[k]) // 10**9,
                                                nanosec=int(ev.t[k]) % 10**9),
                                            polarity=bool(ev.p[k])) for k in range(n)])
        _put('dvs_cdr', f'dvs_{i}.bin', bytes(ts.serialize_cdr(msg, bags.DVS_EVENT_ARRAY)))
    _put('libcaer_cmp', 'cmp_0.bin', _cmp_words([(0, 1), (1, 5), (2, 10), (3, 20), (3, 2069)]))
    _put('libcaer_cmp', 'cmp_1.bin', _cmp_words([(0, 0), (1, 9), (2, 100), (4, 2048 | 8),
                                                 (5, 0xA5), (5, 0x0F), (1, 10), (3, 7)]))
    _put('libcaer_cmp', 'cmp_2.bin', _cmp_words([(2, 239), (4, 170), (5, 0xFF), (5, 0x01)]))
    seq = random_sequence(rng, 0.02, 20_000)
    ev_lines = b''.join(f'{int(t) // 10**9}.{int(t) % 10**9:09d} {x} {y} {p}\n'.encode()
                        for t, x, y, p in zip(seq.events.t[:60], seq.events.x[:60],
                                              seq.events.y[:60], seq.events.p[:60],
                                              strict=True))
    _put('ecd_events', 'events_0.txt', ev_lines)
    _put('ecd_events', 'events_1.txt', b'# comment\n0.000001 1 2 1\n\n0.5\t3 4 0\r\n')
    _put('ecd_imu', 'imu_0.txt', b'0.0 0.1 9.8 0.0 0.01 -0.02 0.03\n'
                                 b'0.001 0.1 9.8 0.0 0.01 -0.02 0.03\n')
    _put('ecd_groundtruth', 'gt_0.txt', b'0.0 1.0 2.0 3.0 0.0 0.0 0.0 1.0\n'
                                        b'0.01 1.1 2.0 3.0 0.0 0.0 0.7071068 0.7071068\n')
    _put('ecd_calib', 'calib_0.txt', b'199.09 198.73 132.19 110.71 -0.368 0.150 0.0 0.0 0.0\n')
    _put('ecd_calib', 'calib_1.txt', b'200 200 120 90\n')
    bag = CORPUS / 'ros1bag'
    bag.mkdir(parents=True, exist_ok=True)
    ros1bag.write_ros1_bag(bag / 'small.bag', random_sequence(rng, 0.01, 5000),
                           events_per_message=20)
    for cfg in sorted((ROOT / 'config').glob('*.yaml')):
        _put('yaml', cfg.name, cfg.read_bytes())
    _put('yaml', 'small.yaml',
         b'packetizer_node:\n  ros__parameters:\n    events_per_frame: 500\n')
    ev = _events(rng, 30)
    structured = np.zeros(30, [('x', '<u2'), ('y', '<u2'), ('p', '<i2'), ('t', '<i8')])
    for k in 'txyp':
        structured[k] = getattr(ev, k) // (1000 if k == 't' else 1)
    for name, arr in (('structured.npy', structured),
                      ('columns.npy', np.stack([ev.t // 1000, ev.x, ev.y, ev.p], 1))):
        buf = io.BytesIO()
        np.save(buf, arr)
        _put('npy', name, buf.getvalue())
    buf = io.BytesIO()
    np.savez(buf, t=ev.t // 1000, x=ev.x, y=ev.y, p=ev.p)
    _put('npz', 'events.npz', buf.getvalue())


if __name__ == '__main__':
    main()
