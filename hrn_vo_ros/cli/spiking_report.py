"""``hrn-vo spiking-report CONFIG [--seconds S] [--seed K] [--set spiking.KEY=VALUE]``.

Prints the resources of the sparse spiking network for a resonator params file
(:mod:`hrn_vo_ros.core.spiking.report`): neurons, synapses, cores and chips per layer group and
in total against the documented Loihi 2 limits, and (unless ``--static``) the per-iteration
spikes, synaptic operations, energy and latency measured on a simulated rotation sequence
(``--seconds`` of seed ``--seed``, packetized with the file's settings as ``hrn-vo run`` does),
next to the dense reference form, the float fast path's CPU operation count and measured time,
and the emulation's frames/s. ``docs/spiking.md`` explains the figures and their sources.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.cli.run import parse_overrides
from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.events.frames import frames_from_events
from hrn_vo_ros.core.events.packet_config import with_calibration
from hrn_vo_ros.core.hrn.config import geometry, needs_focal
from hrn_vo_ros.core.sim.simulator import simulate
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.report import report
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io.yamlconfig import load_configs


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``spiking-report`` subcommand."""
    p = sub.add_parser('spiking-report', help='neurons, synapses, cores, energy and time of the '
                       'spiking network for a config', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('config', type=Path, help='resonator params file (config/*.yaml)')
    p.add_argument('--seconds', type=float, default=2.0,
                   help='simulated rotation sequence to measure on (default 2 s)')
    p.add_argument('--seed', type=int, default=101, help='its seed (default 101)')
    p.add_argument('--frames', type=int, default=200, help='use at most N frames (default 200)')
    p.add_argument('--static', action='store_true', help='resources only: no measured run')
    p.add_argument('--no-dense', action='store_true',
                   help='skip the dense reference run (its synaptic ops are then not printed)')
    p.add_argument('--set', dest='overrides', action='append', default=[], metavar='KEY=VALUE',
                   help='resonator (cleanup.gamma=0.6) or spiking (spiking.steps_per_cycle=16) '
                        'override')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build the network, optionally measure it, print the report."""
    if not args.config.is_file():
        raise DatasetError('config file not found', path=args.config)
    pk_over, rs_over = parse_overrides(args.overrides)
    sp_over = {k.removeprefix('spiking.'): rs_over.pop(k) for k in list(rs_over)
               if k.startswith('spiking.')}
    scfg = from_dict(SpikingConfig, sp_over, source='--set')
    pcfg, cfg = load_configs(args.config, packetizer=pk_over, resonator=rs_over)
    frames = None
    seq = None
    if not args.static:
        seq = simulate('rotation', args.seconds, seed=args.seed)
        pcfg = with_calibration(pcfg, seq.calib)
    if needs_focal(cfg):
        fx = (seq.calib.fx if seq is not None else simulate('rotation', 0.01, seed=0).calib.fx)
        pcfg, cfg = load_configs(args.config, packetizer=pk_over,
                                 resonator={**rs_over, 'focal_px': fx / pcfg.factor})
        if seq is not None:
            pcfg = with_calibration(pcfg, seq.calib)
    if seq is not None:
        t, imgs = frames_from_events(seq.events, pcfg)
        frames = (t[:args.frames], imgs[:args.frames])
    g = geometry(cfg)
    echo(f'spiking report: {args.config} (canvas {g.canvas_width}x{g.canvas_height}, '
         f'log-polar {cfg.logpolar.n_theta}x{cfg.logpolar.n_rho}); {scfg}')
    for line in report(cfg, scfg, frames, dense=not args.no_dense):
        echo(line)
    return 0
