"""``hrn-vo demo [DATASET]``: the whole pipeline through the real ROS 2 node graph, in one command.

Without DATASET it simulates a sequence (``--kind``, ``--seconds``, ``--seed``) in the Event
Camera Dataset layout; with one it uses that folder or zip, or a ROS 2 bag (an EventPacket
topic in any supported encoding and optionally an Imu topic, ``--events-topic`` and
``--imu-topic``; the graph subscribes to its standard topics, so the bag's must be those). A
dataset is converted to a ROS 2 bag. Then it starts the real node processes (bag_recorder,
resonator_node, packetizer_node, and the bag player replaying the bag), waits until every
event frame came out as an estimate, stops the graph, and writes into ``--out``:

* ``graph_bag/`` — the recorded outputs (raw readouts, odometry, poses);
* ``est.csv`` — the raw estimates from the graph (the columns of ``hrn-vo run``);
* ``evaluation.txt`` and ``evaluation.json`` — the paper's evaluation against the ground truth;
* ``trajectory.png`` — the calibrated trajectory against the ground truth (tracking states
  shaded when the estimates carry them);

A bag has no ground truth: the evaluation and the plot are skipped (and the demo says so).
* ``logs/`` — one log per node process; ``input_bag/`` (and ``sequence/`` when simulated).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
import time

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.errors import ConfigError

KIND_CONFIGS = {'rotation': 'shapes_rotation.yaml', 'translation': 'shapes_translation.yaml',
                'arm': 'robot_arm.yaml'}


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``demo`` subcommand."""
    p = sub.add_parser('demo', help='simulate (or take) a sequence, replay it through the node '
                       'graph, record, evaluate, plot', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('dataset', type=Path, nargs='?', default=None,
                   help='Event Camera Dataset folder or zip, or a ROS 2 bag (default: simulate '
                        'one)')
    p.add_argument('--events-topic', default=None,
                   help='bag input: the EventPacket topic (default: the only one)')
    p.add_argument('--imu-topic', default=None,
                   help='bag input: the Imu topic to fuse (default: none)')
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
    from hrn_vo_ros.cli.graph import run_graph

    out: Path = args.out
    if any((out / d).exists() for d in ('sequence', 'input_bag', 'graph_bag')):
        raise ConfigError(f'{out} holds a previous demo: pass another --out or delete it')
    out.mkdir(parents=True, exist_ok=True)
    config = args.config or config_dir() / KIND_CONFIGS[args.kind]
    if not config.is_file():
        raise ConfigError(f'parameter file {config} not found: pass --config FILE')
    t_start = time.monotonic()
    from hrn_vo_ros.io.pipeline import is_bag

    bag_input = args.dataset is not None and is_bag(args.dataset)
    imu = args.imu
    if bag_input:
        bag = check_bag(args)
        imu = args.imu_topic is not None
        dataset = None
    else:
        dataset = args.dataset if args.dataset is not None else simulate(args, out / 'sequence')
        bag = convert(dataset, out / 'input_bag')
    echo(f'[demo] replaying {bag} through the node graph (logs in {out / "logs"})')
    result = run_graph(bag, out / 'graph_bag', out / 'logs', params_file=config,
                       dataset=dataset, imu=imu, rate=args.rate, timeout=args.timeout)
    echo(f'[demo] {result.packets_in}/{result.packets} event packets received, '
         f'{result.frames} frames made, {result.estimates} estimates recorded (none lost), '
         f'graph ran {result.seconds:.1f} s')
    est_csv = write_est_csv(out / 'graph_bag', out / 'est.csv')
    names = ['graph_bag', 'est.csv', 'logs']
    if dataset is None:
        echo('[demo] the bag has no ground truth: evaluation and plot skipped')
    else:
        echo(evaluate(dataset, est_csv, args.kind, out))
        names[2:2] = ['evaluation.txt', 'evaluation.json', 'trajectory.png']
    echo(f'[demo] done in {time.monotonic() - t_start:.0f} s. Files in {out}:')
    for name in names:
        echo(f'  {out / name}')
    return 0


def check_bag(args: argparse.Namespace) -> Path:
    """The bag input, checked against the topics the node graph subscribes to.

    Raises:
        ConfigError: when the events or Imu topic is not the graph's.
    """
    from hrn_vo_ros.io.convert import EVENTS_TOPIC, IMU_TOPIC
    from hrn_vo_ros.io.pipeline import inspect_bag

    bag: Path = args.dataset
    info = inspect_bag(bag, args.events_topic)
    if info.events_topic != EVENTS_TOPIC:
        raise ConfigError(f'{bag}: the node graph subscribes to {EVENTS_TOPIC}, the events are '
                          f'on {info.events_topic}: run `hrn-vo run {bag} --events-topic '
                          f'{info.events_topic}` instead')
    if args.imu_topic is not None and args.imu_topic != IMU_TOPIC:
        raise ConfigError(f'{bag}: the node graph subscribes to {IMU_TOPIC} for the gyro, not '
                          f'{args.imu_topic}')
    echo(f'[demo] {bag}: {info.events_topic} ({info.encoding}, {info.sensor_size[0]}x'
         f'{info.sensor_size[1]}, {info.messages} messages)')
    return bag


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
    from hrn_vo_ros.cli.graph import READOUT_TOPIC
    from hrn_vo_ros.io.estimates import write_estimates
    from hrn_vo_ros.io.recording import read_readout_estimates

    ef = read_readout_estimates(bag, READOUT_TOPIC)
    return write_estimates(dst, ef.series, quality=ef.quality, state=ef.state)


def evaluate(dataset: Path, est_csv: Path, kind: str, out: Path) -> str:
    """Evaluate, write the table, JSON and plot; returns the table."""
    from hrn_vo_ros.cli.evaluate import format_states, format_table, sample_states, state_summary
    from hrn_vo_ros.core.evaluation.protocol import evaluate as ev
    from hrn_vo_ros.io.ecd import read_groundtruth
    from hrn_vo_ros.io.estimates import read_estimate_file
    from hrn_vo_ros.io.plots import plot_evaluation

    gt = read_groundtruth(dataset)
    ef = read_estimate_file(est_csv)
    res = ev(gt, ef.series, kind)
    table = format_table(res)
    states = None
    if ef.state is not None:
        t0 = int(gt.t[0])
        table += '\ntime per state:\n' + format_states(
            state_summary(res, ef.series.t, ef.state, t0), res.series.err_label)
        states = sample_states(res, ef.series.t, ef.state, t0)
    (out / 'evaluation.txt').write_text(table + '\n')
    (out / 'evaluation.json').write_text(json.dumps(res.to_dict()) + '\n')
    plot_evaluation(res, out / 'trajectory.png', title=f'hrn-vo demo: {dataset.name}',
                    states=states)
    return table
