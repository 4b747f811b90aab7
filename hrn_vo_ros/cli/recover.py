"""``hrn-vo recover PARTIAL [DST]``: salvage an interrupted recording as a complete bag.

A ``bag_recorder`` that was killed (SIGKILL, a crash) leaves ``NAME.partial``: its MCAP file
has every chunk the recorder flushed (at least once a second) but no summary and no
``metadata.yaml``, so no reader opens it. This rewrites the messages of every complete chunk,
in their recorded order, as the bag ``DST`` (default ``NAME`` beside ``NAME.partial``) with
its summary, CRCs, statistics, ``metadata.yaml`` and the recorded QoS; messages after the last
complete chunk are lost. ``NAME.partial`` is left as it was: delete it once the recovered bag
checks out (``hrn-vo check DST``). For an interrupted ``hrn-vo convert`` convert again instead.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.io.bags import recover_bag


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``recover`` subcommand."""
    p = sub.add_parser('recover', help='salvage an interrupted recording (.partial) as a bag',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('partial', type=Path, help='the NAME.partial directory (or its .mcap file)')
    p.add_argument('dst', type=Path, nargs='?', default=None,
                   help='the bag to create (default NAME beside NAME.partial)')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Recover the bag and print what it holds."""
    res = recover_bag(args.partial, args.dst)
    for topic, n in sorted(res.counts.items()):
        echo(f'{topic}: {n} messages')
    if res.start_ns is not None and res.end_ns is not None:
        echo(f'bag time {res.start_ns} .. {res.end_ns} ns '
             f'({(res.end_ns - res.start_ns) / 1e9:.3f} s)')
    echo(f'{res.chunks} complete chunk(s) salvaged; {res.dropped_bytes} trailing bytes left out '
         f'({res.stop_reason})')
    echo(f'{res.dst}: written; {args.partial} left as it was (delete it once checked)')
    return 0
