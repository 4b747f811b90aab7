"""``hrn-vo play BAG [--rate F | --max-rate] [--topics T ...] [--clock]``: publish a ROS 2 bag.

For machines without ``ros2 bag play``: every topic is published with its recorded type (raw
CDR) and QoS, in real time, ``--rate`` times faster, or as fast as reliable (KEEP_ALL)
subscribers keep up (``--max-rate``; best-effort subscribers may then drop messages).
``--clock`` adds ``/clock`` for ``use_sim_time`` nodes. Prints the messages sent per topic when
the bag is done. Same as the ``bag_player`` node.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import time

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.io.playback import PlaybackConfig


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``play`` subcommand."""
    p = sub.add_parser('play', help='publish a ROS 2 bag (raw CDR, recorded QoS, /clock)',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bag', type=Path, help='ROS 2 bag directory')
    speed = p.add_mutually_exclusive_group()
    speed.add_argument('--rate', type=float, default=1.0, help='speed factor (default 1)')
    speed.add_argument('--max-rate', action='store_true',
                       help='ignore timing: as fast as reliable KEEP_ALL subscribers keep up')
    p.add_argument('--reliable', action='store_true',
                   help='publish every topic RELIABLE (lossless replay into reliable '
                   'subscribers; recorded best-effort topics do not match them otherwise)')
    p.add_argument('--topics', nargs='+', default=[], metavar='TOPIC',
                   help='only these topics (default all)')
    p.add_argument('--clock', action='store_true', help='publish /clock following the bag')
    p.add_argument('--clock-hz', type=float, default=100.0, help='largest /clock rate')
    p.add_argument('--wait-for-subscribers', type=int, default=0, metavar='N',
                   help='wait until each event topic has N subscribers')
    p.add_argument('--wait-topics', nargs='+', default=[], metavar='TOPIC',
                   help='the topics --wait-for-subscribers waits on (default: the event '
                   'topics), e.g. /event_camera/events /imu')
    p.add_argument('--wait-timeout', type=float, default=30.0, metavar='S',
                   help='stop waiting for subscribers after S seconds (default 30)')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Play the bag, then print the messages sent per topic."""
    cfg = PlaybackConfig(bag=str(args.bag), rate=args.rate, max_rate=args.max_rate,
                         reliable=args.reliable,
                         topics=tuple(args.topics), clock=args.clock, clock_hz=args.clock_hz,
                         wait_for_subscribers=args.wait_for_subscribers,
                         wait_topics=tuple(args.wait_topics), wait_timeout_s=args.wait_timeout)
    import rclpy  # only this subcommand needs ROS

    from hrn_vo_ros.nodes.bag_player import BagPlayer

    rclpy.init(args=[])
    node = None
    try:
        node = BagPlayer(cfg)
        start = time.monotonic()
        sent = node.play()
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    total = sum(sent.values())
    echo(f'played {args.bag} in {time.monotonic() - start:.1f} s: {total} messages '
         f'({", ".join(f"{t} {n}" for t, n in sent.items())})')
    return 0
