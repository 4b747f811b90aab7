"""Spiking vs float backend on simulated rotation sequences; precision sweep; emulation speed.

Prints, measured in this run:

1. per seed, over the whole sequence: median |roll|, |h|, |v| difference spiking - float, the
   median geodesic error of both with the evaluation protocol (``core/evaluation.py``) and its
   difference; then the medians over seeds against the acceptance thresholds (1.0 deg, 0.5 px,
   0.5 deg);
2. (``--sweep``) on the first seed: steps per cycle T x weight bits (and float-spiking rows,
   which have the same spikes without quantisation), then ablations at T = 32 with 8-bit
   weights (the dense reference, radix 2, delay synapses, ReLU threshold, 4-bit payloads,
   binary spikes, 12-bit transform payloads, stochastic rounding) with accuracy vs the float
   backend and the per-iteration spikes, synaptic operations, Loihi energy/latency estimates,
   next to the float HRN's CPU operation counts (fast and dense path); ``--write-docs`` puts
   the table into docs/spiking.md;
3. the frames/s of the float backend and of the spiking emulation (run back to back);
4. (``--layers``) on the first seed (up to 200 frames): per population of the sparse
   transforms, the relative rms error of its graded payloads against 24-bit ones and the share
   of its neurons they silence (``core/spiking/report.py`` ``PayloadProbe``): where the payload
   width costs;
5. (``--resources``) the resource report of ``hrn-vo spiking-report`` on the first seed's
   frames: neurons, synapses, cores and chips, per-iteration spikes, synaptic operations,
   energy and time with their sources, the dense reference form and the CPU's figures.

The spiking backend runs its default form (``spiking.transform: sparse``: butterfly and
log-polar tap layers); ``--set spiking.transform=dense`` runs the dense reference.

``--synthetic`` runs the same comparison on synthetic event frames of a known smooth shift and
roll (``test/hrn_synth.py``, map learning on) instead of simulated sequences; the "geodesic"
column is then the median roll error against the known motion (deg).

Usage::

    scripts/run.sh python bench/bench_spiking.py --seeds 1-3 --sweep
    scripts/run.sh python bench/bench_spiking.py --seeds 1-100 --cache /tmp/hrn_sim

The machine is shared, so frame rates are medians of per-frame times and the float/spiking
ratio is measured in the same run. BLAS threads are limited to one (multi-threaded BLAS on
96-element matrix-vector products is ~40x slower under load here).
"""

from __future__ import annotations

import os

for _var in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from hrn_vo_ros.cli.run import parse_overrides  # noqa: E402
from hrn_vo_ros.core.configbase import from_dict  # noqa: E402
from hrn_vo_ros.core.evaluation.protocol import EstimateSeries, evaluate  # noqa: E402
from hrn_vo_ros.core.events.frames import frames_from_events  # noqa: E402
from hrn_vo_ros.core.events.packet_config import PacketizerConfig, with_calibration  # noqa: E402
from hrn_vo_ros.core.events.sequence import Trajectory  # noqa: E402
from hrn_vo_ros.core.hrn.backends import BackendConfig, make_backend  # noqa: E402
from hrn_vo_ros.core.hrn.config import needs_focal, ResonatorConfig  # noqa: E402
from hrn_vo_ros.core.sim.simulator import simulate  # noqa: E402
from hrn_vo_ros.core.spiking.accounting import cpu_ops  # noqa: E402
from hrn_vo_ros.core.spiking.config import SpikingConfig  # noqa: E402
from hrn_vo_ros.core.spiking.report import payload_errors, payload_lines, report  # noqa: E402
from hrn_vo_ros.errors import DatasetError  # noqa: E402
from hrn_vo_ros.io.yamlconfig import load_configs  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / 'docs' / 'spiking.md'
BEGIN, END = '<!-- bench_spiking table begin -->', '<!-- bench_spiking table end -->'


def seeds_arg(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(','):
        a, _, b = part.partition('-')
        out += list(range(int(a), int(b or a) + 1))
    return out


def load(seed: int, seconds: float, cache: Path | None, pcfg: PacketizerConfig
         ) -> tuple[np.ndarray, np.ndarray, Trajectory]:
    """Frames (t, images) and ground truth of simulated rotation sequence ``seed``, packetized
    (and rectified) with the config's packetizer settings and the sequence's calibration, as
    ``hrn-vo run`` does."""
    name = f'rotation_{seconds:g}s_seed{seed}_{pcfg.events_per_frame}_{pcfg.rectify}.npz'
    path = None if cache is None else cache / name
    if path is not None and path.exists():
        d = np.load(path)
        return d['t'], d['imgs'], Trajectory(d['gt_t'], d['gt_pos'], d['gt_quat'])
    seq = simulate('rotation', seconds, seed=seed)
    t, imgs = frames_from_events(seq.events, with_calibration(pcfg, seq.calib))
    gt = seq.groundtruth
    assert gt is not None
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, t=t, imgs=imgs, gt_t=gt.t, gt_pos=gt.pos, gt_quat=gt.quat)
    return t, imgs, gt


def load_synthetic(seed: int, n: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Synthetic frames of a known motion (h, v px, roll rad) from test/hrn_synth.py."""
    sys.path.insert(0, str(ROOT / 'test'))
    from hrn_synth import event_frame, random_scene, trajectory
    rng = np.random.default_rng(seed)
    scene = random_scene(rng)
    traj = trajectory(n, amp_xy=12.0, amp_roll=0.5, period=250.0)
    imgs = np.array([event_frame(scene, tuple(p), rng) for p in traj])
    return np.arange(n, dtype=np.int64) * 5_000_000, imgs, traj[:, :3]


SYNTH_CFG = {'cleanup': {'gamma': 0.6}, 'map': {'mu1': 0.99, 'mu2': 0.002}}


def run(cfg: ResonatorConfig, backend: BackendConfig, t: np.ndarray, imgs: np.ndarray,
        seed: int) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
    """Readouts (n, 3), per-frame seconds, and the mean per-iteration accounting."""
    b = make_backend(cfg, rng=np.random.default_rng(seed), backend=backend)
    out = np.zeros((len(t), 3))
    dt = np.zeros(len(t))
    acc: list[dict[str, float]] = []
    for i in range(len(t)):
        t0 = time.perf_counter()
        e = b.step(imgs[i], int(t[i]))
        dt[i] = time.perf_counter() - t0
        out[i] = e.h, e.v, e.r
        summary = getattr(b, 'account_summary', None)
        if summary is not None and i % 10 == 0:
            acc.append(summary())
    mean = {k: float(np.mean([a[k] for a in acc if a])) for k in (acc[-1] if acc else {})}
    return out, dt, mean


def geodesic(gt: Trajectory | np.ndarray, t: np.ndarray, est: np.ndarray) -> float:
    if isinstance(gt, np.ndarray):            # synthetic: median roll error vs the truth
        return differences(est[30:], gt[30:])[0]
    try:
        res = evaluate(gt, EstimateSeries(t.astype(np.int64), est[:, 0], est[:, 1], est[:, 2]),
                       'rotation')
    except DatasetError as err:              # e.g. a variant that does not move at all
        print(f'  (not evaluated: {err})', flush=True)
        return float('nan')
    return res.metrics['median_angle_deg']


def differences(a: np.ndarray, b: np.ndarray, period: tuple[float, float, float] = (
        96.0, 72.0, 2 * np.pi)) -> tuple[float, float, float]:
    """Median |roll| (deg), |h|, |v| (px) differences, modulo the codebook periods.

    The readouts are unwrapped over time, so a jump during the first, unconverged frames leaves
    a constant offset of whole periods (the same torus position); the evaluation protocol
    removes such constant offsets (roll zeroing, Umeyama translation), so they are not counted.
    """
    per = np.asarray(period)
    d = np.abs((a - b + per / 2) % per - per / 2)
    return float(np.degrees(np.median(d[:, 2]))), float(np.median(d[:, 0])), float(
        np.median(d[:, 1]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--seeds', type=seeds_arg, default=seeds_arg('1-3'))
    ap.add_argument('--seconds', type=float, default=10.0)
    ap.add_argument('--frames', type=int, default=0, help='use only the first N frames')
    ap.add_argument('--sweep', action='store_true', help='T x weight-bits table (first seed)')
    ap.add_argument('--write-docs', action='store_true', help=f'write the table into {DOC}')
    ap.add_argument('--resources', action='store_true',
                    help='print the resource report on the first seed (up to 300 frames)')
    ap.add_argument('--layers', action='store_true',
                    help='per population of the sparse transforms, on the first seed (up to 200 '
                         'frames): its payload rounding against 24-bit payloads')
    ap.add_argument('--cache', type=Path, default=None, help='cache simulated frames here')
    ap.add_argument('--synthetic', action='store_true',
                    help='known-motion synthetic frames instead of simulated sequences')
    ap.add_argument('--config', type=Path, default=None,
                    help='resonator parameter file (default: config/shapes_rotation.yaml for '
                         'simulated sequences, the core defaults with --synthetic)')
    ap.add_argument('--set', dest='overrides', action='append', default=[], metavar='KEY=VALUE',
                    help='resonator override (cleanup.gamma=0.6) or spiking one '
                         '(spiking.steps_per_cycle=16)')
    args = ap.parse_args()
    _, rs_over = parse_overrides(args.overrides)
    sp_over = {k.removeprefix('spiking.'): rs_over.pop(k) for k in list(rs_over)
               if k.startswith('spiking.')}
    if args.synthetic:
        rs_over = {**{f'{a}.{b}': v for a, d in SYNTH_CFG.items() for b, v in d.items()},
                   **rs_over}
    if args.config is None and not args.synthetic:   # the tuned config, as hrn-vo run uses
        args.config = ROOT / 'config' / 'shapes_rotation.yaml'
    pcfg, cfg = load_configs(args.config, resonator=rs_over)
    if needs_focal(cfg) and not args.synthetic:
        # as hrn-vo run: fx / downsample of the simulated camera (calib.txt)
        fx = simulate('rotation', 0.01, seed=0).calib.fx
        pcfg, cfg = load_configs(args.config,
                                 resonator={**rs_over, 'focal_px': fx / pcfg.factor})
    spk = BackendConfig('spiking', from_dict(SpikingConfig, sp_over))
    flt = BackendConfig('float')
    print(f'resonator: {cfg.width}x{cfg.height}, nonlinearity {cfg.cleanup.nonlinearity}, '
          f'gamma {cfg.cleanup.gamma}; packetizer: rectify {pcfg.rectify}; spiking: '
          f'{spk.spiking}')
    rows = []
    times_f: list[np.ndarray] = []
    times_s: list[np.ndarray] = []
    first: tuple[np.ndarray, np.ndarray, Any, np.ndarray, float] | None = None
    for seed in args.seeds:
        t, imgs, gt = (load_synthetic(seed) if args.synthetic
                       else load(seed, args.seconds, args.cache, pcfg))
        if args.frames:
            t, imgs = t[:args.frames], imgs[:args.frames]
            if isinstance(gt, np.ndarray):    # synthetic truth: one row per frame
                gt = gt[:args.frames]
        ef, dtf, _ = run(cfg, flt, t, imgs, seed)
        es, dts, _ = run(cfg, spk, t, imgs, seed)
        times_f.append(dtf)
        times_s.append(dts)
        gf, gs = geodesic(gt, t, ef), geodesic(gt, t, es)
        droll, dh, dv = differences(es, ef)
        rows.append((droll, dh, dv, gf, gs))
        print(f'seed {seed:3d}: {len(t)} frames  median |d roll| {droll:6.2f} deg  |d h| '
              f'{dh:6.2f} px  |d v| {dv:6.2f} px  geodesic float {gf:6.2f} spiking {gs:6.2f} '
              f'(diff {gs - gf:+.2f}) deg', flush=True)
        if first is None:
            first = (t, imgs, gt, ef, gf)
    r = np.array(rows)
    med = np.median(r, axis=0)
    gdiff = float(np.median(np.abs(r[:, 4] - r[:, 3])))
    print(f'\nover {len(rows)} seeds (median of per-seed medians):')
    print(f'  |d roll| {med[0]:.2f} deg (<= 1.0: {"ok" if med[0] <= 1.0 else "FAIL"})')
    print(f'  |d h| {med[1]:.2f} px, |d v| {med[2]:.2f} px (<= 0.5: '
          f'{"ok" if max(med[1], med[2]) <= 0.5 else "FAIL"})')
    verdict = ('not evaluated: too few frames for the protocol' if np.isnan(gdiff)
               else 'ok' if gdiff <= 0.5 else 'FAIL')
    print(f'  geodesic float {med[3]:.2f} deg, spiking {med[4]:.2f} deg, median |diff| '
          f'{gdiff:.2f} deg (<= 0.5: {verdict})')
    ff = 1.0 / np.median(np.concatenate(times_f))
    fs = 1.0 / np.median(np.concatenate(times_s))
    print(f'  frames/s (median per-frame time): float {ff:.0f}, spiking emulation {fs:.1f} '
          f'(>= 50: {"ok" if fs >= 50 else "FAIL"}), ratio float/spiking {ff / fs:.1f}')
    if args.resources and first is not None:
        print_resources(cfg, spk.spiking, first[0], first[1])
    if args.layers and first is not None:
        print()
        probe = payload_errors(cfg, spk.spiking, first[0][:200], first[1][:200])
        for line in payload_lines(probe, spk.spiking):
            print(line, flush=True)
    if args.sweep and first is not None:
        table = sweep(cfg, first, args.seeds[0])
        print('\n' + table)
        if args.write_docs:
            write_docs(table)
    return 0


def print_resources(cfg: ResonatorConfig, sc: SpikingConfig, t: np.ndarray,
                    imgs: np.ndarray) -> None:
    """The resource report of ``hrn-vo spiking-report`` on up to 300 of these frames."""
    print('\nresources (hrn-vo spiking-report):')
    for line in report(cfg, sc, (t[:300], imgs[:300])):
        print(line, flush=True)


def sweep(cfg: ResonatorConfig, first: tuple[np.ndarray, np.ndarray, Any, np.ndarray, float],
          seed: int) -> str:
    t, imgs, gt, ef, gf = first
    g = make_backend(cfg, rng=np.random.default_rng(0)).geometry
    ops = cpu_ops({'wc': g.canvas_width, 'hc': g.canvas_height, 'n_theta': g.n_theta,
                   'n_rho': g.n_rho, 'k_h': g.canvas_width, 'k_v': g.canvas_height,
                   'k_r': g.n_theta})
    what = ('synthetic known-motion frames (test/hrn_synth.py; "geodesic" = median roll error '
            'vs the truth)' if isinstance(gt, np.ndarray) else
            f'a {gt.t[-1] * 1e-9 - gt.t[0] * 1e-9:.0f} s simulated rotation sequence')
    lines = [f'Seed {seed}, {len(t)} event frames of {what}; float backend geodesic error '
             f'{gf:.2f} deg. '
             f'Differences are medians over all frames (spiking - float). Loihi figures are '
             f'per resonator iteration (estimates, see core/spiking/accounting.py). CPU float '
             f'HRN per iteration: fast path {ops["fast"] / 1e6:.1f} M flop, dense path '
             f'{ops["dense"] / 1e6:.0f} M flop. "Core" = bindings, marginals and cleanups; the '
             f"rest are the Λ/Λ' transform layers (sparse: butterfly and log-polar tap layers; "
             f'dense: N x N layers). Energy: active operations; "+idle": every compartment '
             f'updated at every step of the iteration (52 pJ each). Rows are the sparse form '
             f'unless marked dense.', '',
             '| T | weights | \\|d roll\\| deg | \\|d h\\| px | \\|d v\\| px | geodesic deg | '
             'spikes | synops (M): all / resonator core | energy (µJ): all / core / +idle | '
             'latency (µs) | emulation frames/s |',
             '|---|---|---|---|---|---|---|---|---|---|---|']
    variants: list[tuple[str, SpikingConfig]] = []
    for steps in (16, 32, 63):
        variants.append(('float (timing only)',
                         SpikingConfig(precision='float', steps_per_cycle=steps)))
        variants += [(f'{bits}-bit', SpikingConfig(steps_per_cycle=steps, weight_bits=bits))
                     for bits in (4, 6, 8)]
    # Ablations at T = 32, 8-bit: realisations and codes other than the default.
    variants += [('8-bit, dense reference', SpikingConfig(transform='dense')),
                 ('8-bit, radix 2', SpikingConfig(max_radix=2)),
                 ('8-bit, delay synapses', SpikingConfig(synapse='delay')),
                 ('8-bit, ReLU threshold p', SpikingConfig(nonlinearity='relu')),
                 ('8-bit, 4-bit payloads', SpikingConfig(payload_bits=4,
                                                         transform_payload_bits=4)),
                 ('8-bit, binary spikes', SpikingConfig(payload_bits=1)),
                 ('8-bit, 12-bit transform payloads', SpikingConfig(transform_payload_bits=12)),
                 ('8-bit, stochastic rounding', SpikingConfig(rounding='stochastic'))]
    for label, sc in variants:
        es, dts, acc = run(cfg, BackendConfig('spiking', sc), t, imgs, seed)
        droll, dh, dv = differences(es, ef)
        gs = geodesic(gt, t, es)
        lines.append(f'| {sc.steps_per_cycle} | {label} | {droll:.2f} | {dh:.2f} | {dv:.2f} | '
                     f'{gs:.2f} | {acc["spikes"]:.3g} | {acc["synops"] / 1e6:.1f} / '
                     f'{acc["synops_core"] / 1e6:.2f} | {acc["energy_uJ"]:.0f} / '
                     f'{acc["energy_core_uJ"]:.1f} / +{acc["energy_idle_uJ"]:.0f} | '
                     f'{acc["time_us"]:.0f} | '
                     f'{1.0 / np.median(dts):.0f} |')
        print(lines[-1], flush=True)
    return '\n'.join(lines)


def write_docs(table: str) -> None:
    text = DOC.read_text()
    if BEGIN not in text or END not in text:
        print(f'{DOC} has no table markers; not written', file=sys.stderr)
        return
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    DOC.write_text(f'{head}{BEGIN}\n{table}\n{END}{tail}')
    print(f'table written to {DOC}')


if __name__ == '__main__':
    sys.exit(main())
