"""``hrn-vo demo [DATASET]``: the whole pipeline through the real ROS 2 node graph, in one command.

Without DATASET it simulates a sequence (``--kind``, ``--seconds``, ``--seed``) in the Event
Camera Dataset layout; with one it uses that folder or zip. Then it converts the sequence to a
ROS 2 bag, starts the real node processes (bag_recorder, resonator_node, packetizer_node, and the
bag player replaying the bag), waits until every event frame came out as an estimate, stops the
graph, and writes into ``--out``:

* ``graph_bag/`` — the recorded outputs (raw readouts, odometry, poses);
* ``est.csv`` — the raw estimates from the graph (the columns of ``hrn-vo run``);
* ``evaluation.txt`` and ``evaluation.json`` — the paper's evaluation against the ground truth;
* ``trajectory.png`` — the calibrated trajectory against the ground truth;
* ``logs/`` — one log per node process; ``input_bag/`` (and ``sequence/`` when simulated).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
import time

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.errors import ConfigError, DatasetError

KIND_CONFIGS = {'rotation': 'shapes_rotation.yaml', 'translation': 'shapes_translation.yaml',
                'arm': 'robot_arm.yaml'}


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``demo`` subcommand."""
    p = sub.add_parser('demo', help='simulate (or take) a sequence, replay it through the node '
                       'graph, record, evaluate, plot', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('dataset', type=Path, nargs='?', default=None,
                   help='Event Camera Dataset folder or zip (default: simulate one)')
    p.add_argument('--config', type=Path, default=None,
                   help='parameter file (default: config/<kind>.yaml of the package)')
    p.add_argument('--imu', action='store_true', help='fuse the gyro (imu.enabled)')
    p.add_argument('--out', type=Path, default=Path('hrn_vo_demo'),
                   help='output folder (default ./hrn_vo_demo; must not hold a previous demo)')
    p.add_argument('--kind', choices=sorted(KIND_CONFIGS), default='rotation',
                   help='motion kind: simulated sequence and evaluation protocol')
    p.add_argument('--seconds', type=float, default=20.0, help='simulated duration (s)')
    p.add_argument('--seed', type=int, default=1, help='simulation seed')
    p.add_argument('--rate', type=float, default=1.0,
                   help='replay rate (1 = real time; 0 = as fast as the graph keeps up)')
    p.add_argument('--timeout', type=float, default=600.0, help='give up after this many s')
    p.set_defaults(func=run)


def config_dir() -> Path:
    """The package's ``config/`` folder (source tree, else the install prefix's share/)."""
    here = Path(__file__).resolve().parents[2] / 'config'
    if here.is_dir():
        return here
    return Path(sys.prefix) / 'share' / 'hrn_vo_ros' / 'config'


def run(args: argparse.Namespace) -> int:
    """Run the demo; prints the errors and where the files are."""
    from hrn_vo_ros.nodes.graph import run_graph

    out: Path = args.out
    if any((out / d).exists() for d in ('sequence', 'input_bag', 'graph_bag')):
        raise ConfigError(f'{out} holds a previous demo: pass another --out or delete it')
    out.mkdir(parents=True, exist_ok=True)
    config = args.config or config_dir() / KIND_CONFIGS[args.kind]
    if not config.is_file():
        raise ConfigError(f'parameter file {config} not found: pass --config FILE')
    t_start = time.monotonic()
    dataset = args.dataset if args.dataset is not None else simulate(args, out / 'sequence')
    bag = convert(dataset, out / 'input_bag')
    echo(f'[demo] replaying {bag} through the node graph (logs in {out / "logs"})')
    result = run_graph(bag, out / 'graph_bag', out / 'logs', params_file=config,
                       dataset=dataset, imu=args.imu, rate=args.rate, timeout=args.timeout)
    echo(f'[demo] {result.packets_in}/{result.packets} event packets received, '
         f'{result.frames} frames made, {result.estimates} estimates recorded (none lost), '
         f'graph ran {result.seconds:.1f} s')
    est_csv = write_est_csv(out / 'graph_bag', out / 'est.csv')
    table = evaluate(dataset, est_csv, args.kind, out)
    echo(table)
    echo(f'[demo] done in {time.monotonic() - t_start:.0f} s. Files in {out}:')
    for name in ('graph_bag', 'est.csv', 'evaluation.txt', 'evaluation.json', 'trajectory.png',
                 'logs'):
        echo(f'  {out / name}')
    return 0


def simulate(args: argparse.Namespace, folder: Path) -> Path:
    """Simulate ``args.kind`` and write it in the Event Camera Dataset layout."""
    from hrn_vo_ros.cli.progress import Progress
    from hrn_vo_ros.core.sim.simulator import simulate as sim
    from hrn_vo_ros.io.ecd import write_sequence

    with Progress(args.seconds * 1000, f'[demo] simulating {args.kind} (seed {args.seed}, '
                  'sequence ms)') as bar:
        seq = sim(args.kind, args.seconds, seed=args.seed,
                  progress=lambda s: bar.advance(1000 * s))
    write_sequence(folder, seq)
    echo(f'[demo] {len(seq.events)} events -> {folder}')
    return folder


def convert(dataset: Path, dst: Path) -> Path:
    """Convert the dataset to a ROS 2 bag (EventPacket mono, IMU, ground truth)."""
    from hrn_vo_ros.io.convert import convert as conv

    stats = conv(dataset, dst)
    echo(f'[demo] converted to {dst}: {stats.events} events in {stats.packets} packets, '
         f'{stats.imu} IMU samples, {stats.poses} ground-truth poses')
    return dst


def write_est_csv(bag: Path, dst: Path) -> Path:
    """The recorded raw readouts as an estimate CSV (``hrn-vo run`` columns)."""
    from hrn_vo_ros.core.evaluation.series import EstimateSeries
    from hrn_vo_ros.io.estimates import write_estimates
    from hrn_vo_ros.io.recording import read_readouts
    from hrn_vo_ros.nodes.graph import READOUT_TOPIC

    t, vals = read_readouts(bag, READOUT_TOPIC)
    if len(t) == 0:
        raise DatasetError(f'{bag} holds no estimates on {READOUT_TOPIC}')
    est = EstimateSeries(t=t, h=vals['h'], v=vals['v'], r=vals['r'], z=vals.get('z'))
    return write_estimates(dst, est)


def evaluate(dataset: Path, est_csv: Path, kind: str, out: Path) -> str:
    """Evaluate, write the table, JSON and plot; returns the table."""
    from hrn_vo_ros.cli.evaluate import format_table
    from hrn_vo_ros.core.evaluation.protocol import evaluate as ev
    from hrn_vo_ros.io.ecd import read_groundtruth
    from hrn_vo_ros.io.estimates import read_estimates
    from hrn_vo_ros.io.plots import plot_evaluation

    res = ev(read_groundtruth(dataset), read_estimates(est_csv), kind)
    table = format_table(res)
    (out / 'evaluation.txt').write_text(table + '\n')
    (out / 'evaluation.json').write_text(json.dumps(res.to_dict()) + '\n')
    plot_evaluation(res, out / 'trajectory.png', title=f'hrn-vo demo: {dataset.name}')
    return table
