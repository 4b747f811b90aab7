"""``hrn-vo simulate OUT --kind rotation|translation|arm --seconds S --seed K [--family]``.

Simulates a sequence (:func:`hrn_vo_ros.core.sim.simulator.simulate`; with ``--family`` a
randomized draw of :mod:`hrn_vo_ros.core.sim.family`: seeds 0-99 are tuning draws, 10000 and up
fresh report draws; ``--preset shapes_rotation`` the 60 s shapes_rotation-like preset) and
writes it in the Event Camera Dataset text layout with :func:`hrn_vo_ros.io.ecd.write_sequence`
(``events.txt``, ``imu.txt``, ``groundtruth.txt``, ``calib.txt`` and ``meta.json`` with the
sensor size).
"""

from __future__ import annotations

import argparse
from pathlib import Path
import time

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.cli.progress import Progress
from hrn_vo_ros.core.sim.family import draw, preset, PRESETS, simulate_draw
from hrn_vo_ros.core.sim.simulator import describe_motion, KINDS, simulate, SimulatorConfig
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.ecd import write_sequence


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``simulate`` subcommand."""
    p = sub.add_parser('simulate', help='simulate an event-camera sequence (ECD text layout)',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('out', type=Path, help='new sequence folder (must not exist)')
    p.add_argument('--kind', choices=KINDS, default='rotation', help='scene and motion')
    p.add_argument('--seconds', type=float, default=None,
                   help='duration (default 20; a preset: its own, 60 for shapes_rotation)')
    p.add_argument('--seed', type=int, default=0, help='random seed (default 0)')
    p.add_argument('--speed-scale', type=float, default=1.0,
                   help='multiply motion speeds (default 1)')
    p.add_argument('--noise-rate', type=float, default=None,
                   help='background-activity events per pixel per second (default 0.1)')
    p.add_argument('--family', action='store_true',
                   help='a randomized draw of the simulator family (scene, camera, sensor, '
                        'motion, IMU from --seed; --speed-scale and --noise-rate ignored)')
    p.add_argument('--preset', choices=PRESETS, default=None,
                   help='a fixed family preset (implies --family; --kind ignored)')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Simulate and write; prints a summary line."""
    out: Path = args.out
    if out.exists():
        raise DatasetError('already exists: choose a new folder or delete the old one',
                           path=out)
    d = None
    if args.preset is not None:
        d = preset(args.preset, args.seed)
    elif args.family:
        d = draw(args.kind, args.seed)
    default_s = d.seconds if args.preset is not None and d is not None else 20.0
    seconds = float(args.seconds if args.seconds is not None else default_s)
    kind = args.kind if d is None else d.kind
    start = time.monotonic()
    with Progress(seconds * 1000, f'simulating {kind} (sequence ms)') as bar:
        if d is not None:
            echo(d.summary())
            seq = simulate_draw(d, seconds, progress=lambda s: bar.advance(1000 * s))
        else:
            kw = {'speed_scale': args.speed_scale}
            if args.noise_rate is not None:
                kw['noise_rate_hz'] = args.noise_rate
            seq = simulate(kind, seconds, seed=args.seed, config=SimulatorConfig(**kw),
                           progress=lambda s: bar.advance(1000 * s))
    sim_s = time.monotonic() - start
    write_sequence(out, seq)
    info = describe_motion(seq)
    echo(f'wrote {out}: {kind} {seconds:g} s seed {args.seed}, '
         f'{seq.calib.width}x{seq.calib.height}, {int(info["events"])} events '
         f'({info["events_per_s"] / 1e3:.0f} k/s, {100 * info["on_fraction"]:.1f} % ON), '
         f'peak {info.get("peak_deg_s", 0):.0f} deg/s, {info.get("peak_m_s", 0):.2f} m/s, '
         f'simulated in {sim_s:.1f} s, total {time.monotonic() - start:.1f} s')
    return 0
