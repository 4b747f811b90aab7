"""``hrn-vo run INPUT --config CFG.yaml --out est.csv [--tum est.tum] [--imu] [--seed K]
[--set KEY=VALUE]``.

INPUT is an Event Camera Dataset folder or zip, or a ROS 2 bag (folder or .mcap/.db3 file) with
an EventPacket topic in any supported encoding (mono, evt3, libcaer_cmp, libcaer;
``--events-topic``, default the only one) and optionally an Imu topic (``--imu-topic``; its
gyro then drives the prediction step). For a bag the sensor size comes from the messages and
the estimate times are in the clock of the EventPacket header stamps (``io.pipeline``
explains the mapping); a bag has no calib.txt, so the rectification's intrinsics come from the
config's ``calib.*``, else from the bag's first calibrated CameraInfo (plumb-bob), as the
packetizer node takes them, and the focal length from ``focal_px``, else from that CameraInfo
(fx / D, as the resonator node); ``--set packetizer.rectify=none`` runs unrectified.
``--sensor-size WxH``
overrides the sensor size of the input (with a warning when they differ); a dataset without
meta.json takes it from ``--sensor-size`` or the config's packetizer section.

The estimate CSV gains the columns ``quality`` (tracking quality, 0..1) and ``state``
(tracking, degraded or lost); every frame keeps a row. ``--tum FILE`` also writes the estimate
as a TUM trajectory ``timestamp tx ty tz qx qy qz qw``: the camera's optical frame (x right, y
down, z forward) relative to the first frame; the rotation kind (``odometry.motion_model``
rotation) gives the orientation from h, v, r at the focal length f in frame pixels
(``focal_px``, else ``odometry.focal_length_px``) through ``odometry.projection``: pinhole
Ry(pan) Rx(tilt) Rz(roll) with pan = atan(h/f), tilt = -atan(v/f); equidistant (frames rectified
equidistant) the swing of angle |(h, v)|/f, then Rz(roll); the translation kind the position at
the scene depth; compare with the dataset's groundtruth.txt after aligning the first pose
(docs in ``io.estimates``).

Datasets:

Streams ``events.txt`` of an Event Camera Dataset folder or zip (``io.ecd.iter_events``), makes
fixed-count event frames (``core.events.frames.Packetizer``), runs the HRN on every frame (the
odometry pipeline, ``core.pipeline`` driven by ``io.pipeline``) and writes
the estimate CSV ``t,h,v,r[,z]`` (``io.estimates``): ``t`` packet midpoint in seconds, ``h``, ``v``
camera position in the map in frame pixels, ``r`` roll in radians (right-handed about the optical
axis, unwrapped), ``z`` log scale (when ``scale.enabled``). With ``--imu`` the gyro of
``imu.txt``, integrated between frame times, drives the prediction step, and the packetizer
makes the packets of a fused gyro (``imu.enabled``: ``imu.max_frame_ms``). The sensor size comes
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
from hrn_vo_ros.core.odometry.odometry import OdometryConfig
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.errors import ConfigError, DatasetError
from hrn_vo_ros.io import ecd
from hrn_vo_ros.io.estimates import write_estimates, write_tum
from hrn_vo_ros.io.pipeline import (
    bag_pipeline,
    dataset_pipeline,
    DatasetRun,
    input_configs,
    inspect_bag,
    is_bag,
    read_bag_gyro,
    run_bag,
    run_dataset,
)
from hrn_vo_ros.io.yamlconfig import load_sections, RESONATOR_NODE


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``run`` subcommand."""
    p = sub.add_parser('run', help='run the HRN odometry over a dataset, write an estimate CSV',
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('dataset', type=Path,
                   help='Event Camera Dataset folder or zip, or a ROS 2 bag (EventPacket)')
    p.add_argument('--config', type=Path, default=None,
                   help='parameter file (config/shapes_rotation.yaml, ...); defaults otherwise')
    p.add_argument('--out', type=Path, required=True, help='estimate CSV to write')
    p.add_argument('--tum', type=Path, default=None, metavar='FILE',
                   help='also write a TUM trajectory (timestamp tx ty tz qx qy qz qw): camera '
                        'optical frame (x right, y down, z forward) relative to the first '
                        'frame; rotation kind: orientation from pan/tilt/roll through the '
                        'focal length; compare after aligning the first pose')
    p.add_argument('--imu', action='store_true',
                   help='fuse the gyro of imu.txt (prediction); for a bag use --imu-topic')
    p.add_argument('--events-topic', default=None,
                   help='bag input: the EventPacket topic (default: the only one)')
    p.add_argument('--imu-topic', default=None,
                   help='bag input: an Imu topic whose gyro drives the prediction (default: '
                        'none)')
    p.add_argument('--sensor-size', type=parse_size, default=None, metavar='WxH',
                   help="sensor size; overrides the input's with a warning on mismatch "
                        '(needed for a dataset without meta.json unless the config sets it)')
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


def parse_size(text: str) -> tuple[int, int]:
    """``WxH`` -> (W, H) (argparse type)."""
    w, sep, h = text.lower().partition('x')
    try:
        size = (int(w), int(h))
    except ValueError:
        size = (0, 0)
    if not sep or min(size) <= 0 or max(size) > 65535:
        raise argparse.ArgumentTypeError(f'{text!r}: expected WxH, e.g. 640x480')
    return size


def odometry_config(config: Path | None, focal_px: float, motion_model: str | None = None
                    ) -> OdometryConfig:
    """The readout calibration for ``--tum``: the params file's ``odometry`` section of the
    resonator node, with the resonator's ``focal_px`` as the focal length when it is set."""
    raw: dict[str, Any] = {}
    if config is not None:
        sec = load_sections(config).get(RESONATOR_NODE, {})
        odo = sec.get('odometry')
        if isinstance(odo, dict):
            raw = {k: v for k, v in odo.items() if k in OdometryConfig.__dataclass_fields__}
    if focal_px > 0:
        raw['focal_length_px'] = focal_px
    if motion_model is not None:
        raw['motion_model'] = motion_model
    return from_dict(OdometryConfig, raw, source=str(config or 'defaults'))


def run(args: argparse.Namespace) -> int:
    """Packetize, run the HRN, write the CSV; returns 0."""
    dataset: Path = args.dataset
    if not dataset.exists():
        raise DatasetError('input not found (a dataset folder or zip with events.txt, or a '
                           'ROS 2 bag)', path=dataset)
    bag = is_bag(dataset)
    if not bag and (args.events_topic or args.imu_topic):
        raise ConfigError('--events-topic and --imu-topic are for bag input; '
                          f'{dataset} is a dataset')
    pk_over, rs_over = parse_overrides(args.overrides)
    sp_over = {k.removeprefix('spiking.'): rs_over.pop(k) for k in list(rs_over)
               if k.startswith('spiking.')}
    backend = BackendConfig(args.backend, from_dict(SpikingConfig, sp_over, source='--set'))
    if args.imu and bag:
        raise ConfigError('--imu reads imu.txt of a dataset; for a bag pass --imu-topic TOPIC')
    if args.imu or args.imu_topic:
        rs_over['imu.enabled'] = True
        pk_over['imu.enabled'] = True          # the packets of a fused gyro (imu.max_frame_ms)
    info = inspect_bag(dataset, args.events_topic) if bag else None
    resolved = input_configs(args.config, dataset, bag=info, sensor_size=args.sensor_size,
                             packetizer=pk_over, resonator=rs_over)
    for w in resolved.warnings:
        echo(f'warning: {w}')
    for note in resolved.notes:
        echo(f'note: {note}')
    if args.config is None:
        echo('note: no --config: the defaults, the network of config/live.yaml (no '
             'rectification); config/<kind>.yaml hold the settings of each dataset kind')
    dc = resolved.configs
    rcfg = dc.resonator
    camera_from_imu = np.reshape(np.asarray(rcfg.imu.camera_from_imu, np.float64), (3, 3))

    def make() -> Any:
        return make_backend(rcfg, rng=np.random.default_rng(args.seed), backend=backend)

    quiet = io.StringIO() if args.quiet else None
    result: DatasetRun
    if info is not None:
        echo(f'{dataset}: {info.events_topic} ({info.encoding}, {info.sensor_size[0]}x'
             f'{info.sensor_size[1]}, {info.messages} messages)'
             + (f', gyro of {args.imu_topic}' if args.imu_topic else ''))
        gyro = (read_bag_gyro(dataset, args.imu_topic, camera_from_imu) if args.imu_topic
                else None)
        pipe = bag_pipeline(dc.packetizer, make, gyro=gyro, with_z=rcfg.scale.enabled)
        with Progress(None, 'hrn-vo run', unit='ev', stream=quiet) as bar:
            result = run_bag(info, pipe, on_events=bar.advance)
    else:
        pipe = dataset_pipeline(dataset, dc.packetizer, make, camera_from_imu=camera_from_imu,
                                imu=rcfg.imu.enabled, with_z=rcfg.scale.enabled)
        with Progress(ecd.event_count(dataset), 'hrn-vo run', unit='ev', stream=quiet) as bar:
            result = run_dataset(dataset, pipe, on_events=bar.advance)
    write_estimates(args.out, result.series, quality=result.quality, state=result.state)
    if args.tum is not None:
        write_tum(args.tum, result.series, odometry_config(args.config, rcfg.focal_px))
        echo(f'TUM trajectory -> {args.tum}')
    if isinstance(pipe.estimator, SpikingDiagnostics):
        acc = pipe.estimator.account_summary()
        echo('spiking, per iteration (last frame): ' + ', '.join(
            f'{k} {acc[k]:.4g}' for k in ('spikes', 'synops', 'neuron_updates', 'energy_uJ',
                                          'time_us') if k in acc))
    if result.outside:
        echo(f'{result.outside} events rectified outside the frame (not binned)')
    if result.capped:
        echo(f'{result.capped} events over the rate cap (max_frame_hz '
             f'{dc.packetizer.max_frame_hz:g}) not binned')
    n = len(result.series)
    if info is not None and result.stamp_span_ns is not None:
        t = result.series.t
        a, b = result.stamp_span_ns
        echo(f'{result.events} change events; header stamps {a / 1e9:.6f}..{b / 1e9:.6f} s, '
             f'estimates {t[0] / 1e9:.6f}..{t[-1] / 1e9:.6f} s')
    pk = dc.packetizer
    echo(f'{n} frames of {pk.width}x{pk.height} (downsample {pk.factor:.4g}) in '
         f'{result.seconds:.2f} s ({n / max(result.seconds, 1e-9):.0f} frames/s) -> {args.out}')
    return 0
