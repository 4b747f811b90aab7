"""Throughput of dataset conversion and of the event codecs, measured side by side in one run.

    scripts/run.sh python bench/bench_convert.py [--seconds 20] [--simulate] [--repeats 3]
    scripts/run.sh python bench/bench_convert.py --smoke    # 0.5 s, one repeat: only that it runs

Builds a 20 s sequence (default: synthetic events at ~350 k/s, the rate of a simulated rotation
sequence, ~7 M events; ``--simulate`` runs the project's simulator instead, which is slower),
writes it in the Event Camera Dataset text layout, then times (medians of ``--repeats`` runs):

* parsing ``events.txt`` alone (M lines/s), and streamed from a ``.zip``,
* ``hrn-vo convert`` to MCAP (M events/s; the acceptance figure, target >= 2),
* converting the same sequence from a ROS 1 bag (dvs_msgs/EventArray),
* reading the bag back and decoding mono (M events/s),
* evt3 decoding of the same events (M events/s),

and the ratios between them. The machine is shared: compare ratios, not absolute figures.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import statistics
import sys
import tempfile
import time
import zipfile

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the working tree's package
from hrn_vo_ros.core.events.arrays import EventChecksum
from hrn_vo_ros.core.events.sequence import random_sequence, Sequence
from hrn_vo_ros.io import bags, convert, ecd, eventpacket, ros1bag


def timed(fn: object, repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``fn``."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def make_sequence(args: argparse.Namespace) -> Sequence:
    """The benchmark's sequence: simulated (``--simulate``) or synthetic events."""
    if not args.simulate:
        return random_sequence(np.random.default_rng(0), args.seconds, args.rate, stamps='us')
    from hrn_vo_ros.core.sim.simulator import simulate
    t0 = time.perf_counter()
    seq = simulate('rotation', args.seconds, seed=0)
    print(f'simulated {args.seconds:g} s rotation in {time.perf_counter() - t0:.1f} s')
    return seq


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--seconds', type=float, default=20.0)
    ap.add_argument('--rate', type=float, default=350_000.0, help='synthetic events/s')
    ap.add_argument('--simulate', action='store_true', help='use the simulator (rotation)')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--smoke', action='store_true',
                    help='0.5 s of events, one repeat: only that it runs')
    args = ap.parse_args()
    if args.smoke:
        args.seconds, args.repeats = min(args.seconds, 0.5), 1
    seq = make_sequence(args)
    n = len(seq.events)
    work = Path(tempfile.mkdtemp(prefix='bench_convert_'))
    try:
        t0 = time.perf_counter()
        folder = ecd.write_sequence(work / 'seq', seq)
        write_s = time.perf_counter() - t0
        size = (folder / 'events.txt').stat().st_size
        print(f'{n} events ({n / args.seconds / 1e3:.0f} k/s), events.txt {size / 1e6:.0f} MB, '
              f'written in {write_s:.1f} s ({n / write_s / 1e6:.2f} M lines/s)')

        def parse() -> None:
            for _ in ecd.iter_events(folder):
                pass

        runs = iter(range(10**6))
        stats: list[convert.ConversionStats] = []

        def conv() -> None:
            stats.append(convert.convert(folder, work / f'bag{next(runs)}'))

        def read_back() -> None:
            c = EventChecksum()
            for ev in bags.iter_bag_events(work / 'bag0'):
                c.update(ev)
            assert (c.count, c.hexdigest()) == (stats[0].events, stats[0].checksum)

        with zipfile.ZipFile(work / 'seq.zip', 'w', zipfile.ZIP_DEFLATED, compresslevel=1) as z:
            for p in folder.iterdir():
                z.write(p, p.name)
        ros1bag.write_ros1_bag(work / 'seq.bag', seq, events_per_message=10_000)

        def parse_zip() -> None:
            for _ in ecd.iter_events(work / 'seq.zip'):
                pass

        def conv_ros1() -> None:
            stats.append(convert.convert(work / 'seq.bag', work / f'bag{next(runs)}'))

        sub = seq.events[:min(n, 1_000_000)]
        stream = eventpacket.encode_evt3(sub)
        words = stream.view('<u2')

        def evt3() -> None:
            dec = eventpacket.Evt3Decoder()
            for part in np.array_split(words, 200):
                dec.decode(part.view(np.uint8))

        s_parse = timed(parse, args.repeats)
        s_zip = timed(parse_zip, args.repeats)
        s_conv = timed(conv, args.repeats)
        s_ros1 = timed(conv_ros1, args.repeats)
        s_read = timed(read_back, args.repeats)
        s_evt3 = timed(evt3, args.repeats)
        print(f'parse events.txt   {n / s_parse / 1e6:6.2f} M lines/s  ({s_parse:.2f} s)')
        print(f'parse .zip member  {n / s_zip / 1e6:6.2f} M lines/s  ({s_zip:.2f} s, streamed)')
        print(f'convert to MCAP    {n / s_conv / 1e6:6.2f} M events/s ({s_conv:.2f} s, '
              f'{stats[0].packets} packets)  target >= 2')
        print(f'ROS 1 bag -> MCAP  {n / s_ros1 / 1e6:6.2f} M events/s ({s_ros1:.2f} s)')
        print(f'read bag + decode  {n / s_read / 1e6:6.2f} M events/s ({s_read:.2f} s)')
        print(f'evt3 decode        {len(sub) / s_evt3 / 1e6:6.2f} M events/s '
              f'({stream.size / len(sub):.2f} B/event)')
        print(f'ratios: convert/parse {s_parse / s_conv:.2f}, read/convert {s_conv / s_read:.2f}')
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
