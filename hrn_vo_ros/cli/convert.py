"""``hrn-vo convert SRC DST [--storage S] [--events-per-packet N | --packet-duration MS]``.

Converts an Event Camera Dataset sequence (text folder, its .zip, or its ROS 1 .bag), a NumPy
event file, or a simulated sequence into a ROS 2 bag with ``/event_camera/events``
(EventPacket, mono), ``/imu``, ``/ground_truth/pose`` and ``/event_camera/camera_info``, stamped
in the sensor clock (see :mod:`hrn_vo_ros.io.convert`). Refuses to overwrite DST; an interrupted
run leaves only ``DST.partial``, which no reader accepts.
"""

from __future__ import annotations

import argparse
from contextlib import ExitStack
from pathlib import Path

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.cli.progress import Progress
from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io import convert


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split('x'))
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not WIDTHxHEIGHT, e.g. 240x180') from None
    if not (0 < w <= 65535 and 0 < h <= 32767):
        raise argparse.ArgumentTypeError(f'{text!r}: width 1..65535, height 1..32767')
    return w, h


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``convert`` subcommand."""
    p = sub.add_parser('convert', help='convert a dataset to a ROS 2 bag (EventPacket mono)',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('src', type=Path, help='dataset folder, .zip, ROS 1 .bag, or .npy/.npz')
    p.add_argument('dst', type=Path, help='new ROS 2 bag directory (must not exist)')
    p.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap',
                   help='bag storage (default mcap)')
    size = p.add_mutually_exclusive_group()
    size.add_argument('--events-per-packet', type=int, metavar='N',
                      help='fixed number of events per EventPacket')
    size.add_argument('--packet-duration', type=float, metavar='MS',
                      help=f'fixed packet duration in ms (default '
                      f'{convert.DEFAULT_PACKET_DURATION_MS:g})')
    p.add_argument('--frame-id', default='event_camera', help='frame of events and camera info')
    p.add_argument('--sensor-size', type=_size, metavar='WxH',
                   help='sensor size (needed for NumPy files; overrides the dataset)')
    p.add_argument('--trajectory', type=Path, help='TUM-like ground truth (NumPy sources)')
    p.add_argument('--time-unit', choices=('s', 'ms', 'us', 'ns'), default='us',
                   help='time unit of NumPy event files (default us, as Metavision)')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Convert and print a summary line."""
    if args.events_per_packet is not None and args.events_per_packet < 1:
        raise ConfigError(f'--events-per-packet {args.events_per_packet} must be >= 1')
    with ExitStack() as stack:
        bars: list[Progress] = []

        def on_source(source: convert.Source) -> None:  # after the inputs were checked
            bars.append(stack.enter_context(
                Progress(source.total_events, f'converting {args.src.name}', unit='ev')))

        stats = convert.convert(
            args.src, args.dst, storage=args.storage, events_per_packet=args.events_per_packet,
            packet_duration_ms=args.packet_duration, frame_id=args.frame_id,
            sensor_size=args.sensor_size, trajectory=args.trajectory, time_unit=args.time_unit,
            progress=lambda n: bars[0].advance(n), on_source=on_source)
    echo(f'wrote {args.dst} ({args.storage}) from {stats.source_kind}: {stats.events} events in '
         f'{stats.packets} packets, {stats.imu} imu, {stats.poses} poses, {stats.camera_info} '
         f'camera_info; {stats.seconds:.1f} s, {stats.events_per_second / 1e6:.2f} M events/s; '
         f'checksum {stats.checksum[:16]}')
    return 0
