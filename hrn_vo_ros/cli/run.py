"""``hrn-vo run DATASET --config CFG.yaml --out est.csv [--imu] [--seed K] [--set KEY=VALUE]``.

Streams ``events.txt`` of an Event Camera Dataset folder or zip (``io.ecd.iter_events``), makes
fixed-count event frames (``core.events.frames.Packetizer``), runs the HRN on every frame (the
odometry pipeline, ``core.pipeline`` driven by ``io.pipeline``) and writes
the estimate CSV ``t,h,v,r[,z]`` (``io.estimates``): ``t`` packet midpoint in seconds, ``h``, ``v``
camera position in the map in frame pixels, ``r`` roll in radians (right-handed about the optical
axis, unwrapped), ``z`` log scale (when ``scale.enabled``). With ``--imu`` the gyro of
``imu.txt``, integrated between frame times, drives the prediction step. The sensor size comes
from the dataset; the frame size of the resonator follows the packetizer's.
"""

from __future__ import annotations

import argparse
import io
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.cli.progress import Progress
from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.hrn.backends import BackendConfig, BACKENDS, make_backend, SpikingDiagnostics
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.errors import ConfigError, DatasetError
from hrn_vo_ros.io import ecd
from hrn_vo_ros.io.estimates import write_estimates
from hrn_vo_ros.io.pipeline import dataset_pipeline, run_dataset
from hrn_vo_ros.io.yamlconfig import dataset_configs


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``run`` subcommand."""
    p = sub.add_parser('run', help='run the HRN odometry over a dataset, write an estimate CSV',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('dataset', type=Path, help='Event Camera Dataset folder or zip')
    p.add_argument('--config', type=Path, default=None,
                   help='parameter file (config/shapes_rotation.yaml, ...); defaults otherwise')
    p.add_argument('--out', type=Path, required=True, help='estimate CSV to write')
    p.add_argument('--imu', action='store_true', help='fuse the gyro of imu.txt (prediction)')
    p.add_argument('--seed', type=int, default=0, help='seed of the random initial states')
    p.add_argument('--set', dest='overrides', action='append', default=[], metavar='KEY=VALUE',
                   help='override a resonator parameter (dotted, YAML value), e.g. '
                        'cleanup.gamma=0.6; packetizer ones with a packetizer. prefix')
    p.add_argument('--backend', choices=tuple(BACKENDS), default='float',
                   help='resonator backend: float (reference) or spiking (phasor neurons under '
                        'Loihi constraints; tune with --set spiking.KEY=VALUE, docs/spiking.md)')
    p.add_argument('--quiet', action='store_true', help='no progress bar')
    p.set_defaults(func=run)


def parse_overrides(items: list[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``KEY=VALUE`` strings → (packetizer, resonator) override dicts (values parsed as YAML)."""
    pk: dict[str, Any] = {}
    rs: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition('=')
        if not sep or not key.strip():
            raise ConfigError(f'--set {item!r}: expected KEY=VALUE, e.g. cleanup.gamma=0.6')
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError:
            raise ConfigError(f'--set {item!r}: the value is not valid YAML') from None
        key = key.strip()
        if key.startswith('packetizer.'):
            pk[key.removeprefix('packetizer.')] = value
        else:
            rs[key] = value
    return pk, rs


def run(args: argparse.Namespace) -> int:
    """Packetize, run the HRN, write the CSV; returns 0."""
    dataset: Path = args.dataset
    if not dataset.exists():
        raise DatasetError('dataset not found (a folder or zip with events.txt)', path=dataset)
    pk_over, rs_over = parse_overrides(args.overrides)
    sp_over = {k.removeprefix('spiking.'): rs_over.pop(k) for k in list(rs_over)
               if k.startswith('spiking.')}
    backend = BackendConfig(args.backend, from_dict(SpikingConfig, sp_over, source='--set'))
    if args.imu:
        rs_over['imu.enabled'] = True
    dc = dataset_configs(args.config, dataset, packetizer=pk_over, resonator=rs_over)
    rcfg = dc.resonator
    pipe = dataset_pipeline(
        dataset, dc.packetizer,
        lambda: make_backend(rcfg, rng=np.random.default_rng(args.seed), backend=backend),
        camera_from_imu=np.reshape(np.asarray(rcfg.imu.camera_from_imu, np.float64), (3, 3)),
        imu=rcfg.imu.enabled, with_z=rcfg.scale.enabled)
    with Progress(ecd.event_count(dataset), 'hrn-vo run', unit='ev',
                  stream=io.StringIO() if args.quiet else None) as bar:
        result = run_dataset(dataset, pipe, on_events=bar.advance)
    write_estimates(args.out, result.series)
    if isinstance(pipe.estimator, SpikingDiagnostics):
        acc = pipe.estimator.account_summary()
        echo('spiking, per iteration (last frame): ' + ', '.join(
            f'{k} {acc[k]:.4g}' for k in ('spikes', 'synops', 'neuron_updates', 'energy_uJ',
                                          'time_us') if k in acc))
    if result.outside:
        echo(f'{result.outside} events rectified outside the frame (not binned)')
    n = len(result.series)
    echo(f'{n} frames in {result.seconds:.2f} s ({n / max(result.seconds, 1e-9):.0f} '
         f'frames/s) -> {args.out}')
    return 0
