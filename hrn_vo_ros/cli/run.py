"""``hrn-vo run DATASET --config CFG.yaml --out est.csv [--imu] [--seed K] [--set KEY=VALUE]``.

Streams ``events.txt`` of an Event Camera Dataset folder or zip (``io.ecd.iter_events``), makes
fixed-count event frames (``core.frames.Packetizer``), runs the HRN on every frame and writes
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
import time
from typing import Any

import numpy as np
import yaml

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.cli.progress import Progress
from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.evaluation.protocol import EstimateSeries
from hrn_vo_ros.core.events.frames import Packetizer, with_calibration
from hrn_vo_ros.core.hrn.backends import BackendConfig, BACKENDS, make_backend, SpikingDiagnostics
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.errors import ConfigError, DatasetError
from hrn_vo_ros.io import ecd
from hrn_vo_ros.io.estimates import write_estimates
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
    pcfg, rcfg = dc.packetizer, dc.resonator
    width, height = pcfg.sensor_width, pcfg.sensor_height
    gyro: GyroIntegrator | None = None
    if rcfg.imu.enabled:
        rot = np.asarray(rcfg.imu.camera_from_imu, dtype=np.float64).reshape(3, 3)
        gyro = GyroIntegrator(ecd.read_imu(dataset), rot)
    if pcfg.rectify != 'none':
        pcfg = with_calibration(pcfg, ecd.read_calib(dataset))
    packetizer = Packetizer(pcfg)
    hrn = make_backend(rcfg, rng=np.random.default_rng(args.seed), backend=backend)
    rows: list[tuple[int, float, float, float, float]] = []
    prev_angle: np.ndarray | None = None
    total = ecd.event_count(dataset)
    start = time.perf_counter()
    with Progress(total, 'hrn-vo run', unit='ev',
                  stream=io.StringIO() if args.quiet else None) as bar:
        for batch in ecd.iter_events(dataset, sensor_size=(width, height)):
            for frame in packetizer.push(batch):
                delta = None
                if gyro is not None:
                    angle = gyro.angle_at(frame.t_ns)
                    delta = None if prev_angle is None else angle - prev_angle
                    prev_angle = angle
                e = hrn.step(frame.image, frame.t_ns, gyro_delta=delta)
                rows.append((frame.t_ns, e.h, e.v, e.r, e.z))
            bar.advance(len(batch))
    elapsed = time.perf_counter() - start
    if not rows:
        raise DatasetError(f'fewer events than one packet ({pcfg.events_per_frame}); nothing '
                           'to estimate', path=dataset)
    arr = np.array([r[1:] for r in rows], dtype=np.float64)
    est = EstimateSeries(t=np.array([r[0] for r in rows], dtype=np.int64), h=arr[:, 0],
                         v=arr[:, 1], r=arr[:, 2], z=arr[:, 3] if rcfg.scale.enabled else None)
    write_estimates(args.out, est)
    if isinstance(hrn, SpikingDiagnostics):
        acc = hrn.account_summary()
        echo('spiking, per iteration (last frame): ' + ', '.join(
            f'{k} {acc[k]:.4g}' for k in ('spikes', 'synops', 'neuron_updates', 'energy_uJ',
                                          'time_us') if k in acc))
    if packetizer.outside:
        echo(f'{packetizer.outside} events rectified outside the frame (not binned)')
    echo(f'{len(rows)} frames in {elapsed:.2f} s ({len(rows) / max(elapsed, 1e-9):.0f} '
         f'frames/s) -> {args.out}')
    return 0
