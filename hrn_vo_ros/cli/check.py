"""``hrn-vo check BAG [--topic T]``: verify a ROS 2 bag end to end.

Checks what :func:`hrn_vo_ros.io.bags.verify_bag` checks: the metadata's message counts against
the storage, every MCAP CRC (chunks, data section, summary) or the sqlite integrity check, the
bag-time span, every event message decoded (inside the sensor, times non-decreasing within a
packet), and the event checksum ``hrn-vo convert`` stored in the metadata's ``custom_data``.
Prints one line per topic and exits 0, or names the bag, topic and position of the first problem
and exits with the error's code (4 for a corrupt bag, 3 for an undecodable message).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.io.bags import verify_bag


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``check`` subcommand."""
    p = sub.add_parser('check', help='verify a ROS 2 bag (CRCs, counts, event checksum)',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bag', type=Path, help='ROS 2 bag directory (or .mcap / .db3 file)')
    p.add_argument('--topic', default=None,
                   help='event topic to decode (default: the converted or the only one)')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Verify the bag and print what was checked."""
    res = verify_bag(args.bag, topic=args.topic)
    for topic, n in sorted(res.counts.items()):
        echo(f'{topic}: {n} messages')
    if res.event_topic is not None:
        stored = (': matches the stored checksum' if res.stored_checksum is not None else '')
        echo(f'{res.event_topic}: {res.events} events decoded, checksum {res.checksum}{stored}')
    if res.storage == 'mcap' and res.chunks_crc_checked:
        echo(f'{res.chunks_crc_checked} MCAP chunk CRCs verified')
    for note in res.notes:     # e.g. no stored checksum, chunks without CRCs
        echo(f'note: {note}')
    echo(f'{res.path}: OK ({res.storage})')
    return 0
