"""``hrn-vo evaluate DATASET est.csv --kind rotation|translation|arm [--calib last10|full]
[--convention swing-twist|euler]``.

Evaluates an estimate CSV (``t,h,v,r[,z]``, as ``hrn-vo run`` writes it) against the dataset's
``groundtruth.txt`` with the paper's protocol (:mod:`hrn_vo_ros.core.evaluation.protocol`): lag by
cross-correlation, 70/30 split, Umeyama calibration, median errors on the test part. Prints a
table and, last, one JSON line (``--json``: the JSON line only). ``--plot OUT.png`` draws the
calibrated trajectory against the ground truth. ``--lag-scan MS`` (a diagnostic, not the
protocol) re-evaluates with the lag moved by -MS..+MS in 1 ms steps and reports where the
headline error is lowest (the JSON gets a ``lag_scan`` entry); ``--lag-window training`` (not
the protocol) searches the lag only before the evaluated part, which then fits nothing (a late
jump of the roll moves a whole-run lag, and with it every error); ``--roll-zero S`` (also a
diagnostic) zeroes the roll on the first S seconds of estimates instead of the protocol's
0.1 s. ``--convention`` chooses how pan, tilt and roll make a rotation (default
``swing-twist``, what an image shift and an image rotation measure; ``euler``:
``Ry(pan) Rx(tilt) Rz(roll)``). When the CSV has a ``state`` column (``hrn-vo run``
writes one), the table also gives the time spent in each tracking state (a frame counts until
the next frame) and the median error of the evaluated samples per state (the JSON gets a
``states`` entry), and the plot shades the states. ``--calib-states tracking`` (a diagnostic,
not the protocol; needs that column) fits the calibration on the estimates in the given states
only: when the track was lost inside the calibration segment, the protocol's fit (and so every
error) describes the lost output, and this shows what the tracked part alone gives.
The table's last line (and the JSON's ``motion``) gives the 95th percentile of the camera's
turn and travel from one estimate to the next, i.e. what one event frame spans; a rotation
turning 4° or more per frame gets a note (the network without a gyro loses most tracks there).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.core.evaluation.protocol import (
    CALIB_MODES,
    EVAL_KINDS,
    EvalResult,
    evaluate,
    lag_scan,
    LAG_WINDOWS,
    ROTATION_CONVENTIONS,
)
from hrn_vo_ros.core.evaluation.samples import motion_between
from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io.ecd import read_groundtruth
from hrn_vo_ros.io.estimates import read_estimate_file, STATES

TARGETS = {'rotation': ('median_angle_deg', 'deg'), 'translation': ('median_pos_m', 'm'),
           'arm': ('median_pos_m', 'm')}


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``evaluate`` subcommand."""
    p = sub.add_parser('evaluate', help="evaluate an estimate CSV with the paper's protocol",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('dataset', type=Path, help='sequence folder or zip with groundtruth.txt')
    p.add_argument('estimate', type=Path, help='estimate CSV (t,h,v,r[,z])')
    p.add_argument('--kind', choices=EVAL_KINDS, required=True, help='evaluation protocol')
    p.add_argument('--calib', choices=CALIB_MODES, default='last10',
                   help='rotation calibration segment: last 10 s of the training part '
                        '(default) or all of it')
    p.add_argument('--convention', choices=ROTATION_CONVENTIONS, default='swing-twist',
                   help='pan/tilt/roll convention: swing-twist (default: the swing points the '
                        'optical axis, the roll turns about it) or euler (Ry Rx Rz)')
    p.add_argument('--lag', type=float, default=None,
                   help='use this lag in seconds instead of estimating it')
    p.add_argument('--lag-window', choices=LAG_WINDOWS, default='run',
                   help="where the lag is searched: 'run' (default, the protocol: the whole "
                        "run) or 'training' (only before the evaluated part, so that nothing "
                        "evaluated fits the lag; a late jump of the roll cannot move it)")
    p.add_argument('--lag-scan', type=int, default=0, metavar='MS',
                   help='also evaluate with the lag moved by -MS..+MS ms (1 ms steps) and '
                        'report where the headline error is lowest (diagnostic)')
    p.add_argument('--roll-zero', type=float, default=0.1, metavar='S',
                   help='zero the roll on the estimates of the first S seconds (default 0.1: '
                        'the protocol; longer only as a diagnostic of how much the headline '
                        'depends on the first few event packets)')
    p.add_argument('--calib-states', nargs='+', choices=STATES, default=None, metavar='STATE',
                   help='fit the calibration on the estimates in these states only (e.g. '
                        'tracking; needs the CSV state column; a diagnostic, not the protocol)')
    p.add_argument('--plot', type=Path, default=None, metavar='FILE',
                   help='write a trajectory plot (PNG; the format follows the suffix); an '
                        'existing folder gets trajectory.png inside it (the path is printed)')
    p.add_argument('--json', action='store_true', help='print only the JSON line')
    p.set_defaults(func=run)


def format_table(res: EvalResult) -> str:
    """A human-readable table of the result."""
    rows = [('kind', res.kind), ('calibration', str(res.calibration.get('segment', ''))),
            ('rotation convention', str(res.calibration.get('convention', ''))),
            ('roll zeroed on', f'first {res.calibration.get("roll_zero_s", 0.1)} s of estimates'),
            ('lag', f'{res.lag_s * 1e3:+.1f} ms, searched '
             + ('before the evaluated part' if res.calibration.get('lag_window') == 'training'
                else 'over the whole run')),
            ('roll correlation', f'{res.roll_corr:.3f}'),
            ('estimates used / calib / evaluated',
             f'{res.counts["used"]} / {res.counts["calibration"]} / {res.counts["evaluated"]}'),
            ('split at', f'{res.split_s:.2f} s')]
    rows += [(k, f'{v:.4g}') for k, v in res.metrics.items()]
    rows += [('warning', w) for w in res.warnings]
    width = max(len(k) for k, _ in rows)
    return '\n'.join(f'{k:<{width}}  {v}' for k, v in rows)


def sample_states(res: EvalResult, t_est_ns: np.ndarray, state: list[str],
                  t0_ns: int) -> list[str]:
    """The state of the estimate row behind every evaluated sample of ``res.series`` (its
    times are seconds from the first ground-truth pose ``t0_ns``; estimates were shifted by
    ``-lag``): the row at or before the sample time."""
    t_s = res.series.t_s
    t_ns = t0_ns + np.round((t_s + res.lag_s) * 1e9).astype(np.int64)
    idx = np.clip(np.searchsorted(t_est_ns, t_ns, side='right') - 1, 0, len(state) - 1)
    return [state[i] for i in idx]


def state_summary(res: EvalResult, t_est_ns: np.ndarray, state: list[str],
                  t0_ns: int) -> dict[str, dict[str, float | None]]:
    """Per state: seconds spent in it (each frame until the next one) and the median error of
    the evaluated samples in it (None when none, ``null`` in the JSON line, which stays
    strict JSON)."""
    t = np.asarray(t_est_ns, dtype=np.int64)
    dt = np.diff(t, append=t[-1]) / 1e9 if t.size else np.zeros(0)
    per = sample_states(res, t, state, t0_ns) if t.size else []
    err = res.series.err
    test = res.series.test
    out: dict[str, dict[str, float | None]] = {}
    for name in STATES:
        mask = np.array([s == name for s in per], dtype=bool)
        sel = err[mask & test] if mask.size else np.zeros(0)
        out[name] = {'seconds': float(sum(d for d, s in zip(dt, state, strict=True)
                                          if s == name)),
                     'median_error': float(np.median(sel)) if sel.size else None,
                     'evaluated': int(sel.size)}
    return out


def format_states(summary: dict[str, dict[str, float | None]], err_label: str) -> str:
    """The per-state lines of the table."""
    lines = []
    for name, v in summary.items():
        med = v['median_error']
        error = (f'median error {med:.4g} {err_label} over {int(v["evaluated"] or 0)} evaluated '
                 'samples' if med is not None else 'no evaluated samples')
        lines.append(f'{name:<9} {v["seconds"] or 0.0:8.2f} s, {error}')
    return '\n'.join(lines)


#: The camera's turn between frames from which the network without a gyro loses most tracks
#: (fresh rotation draws of the simulator family: 3 of 28 tracked; docs/results.md).
FAST_TURN_DEG = 4.0


def motion_line(kind: str, turn_deg: float, travel_m: float) -> str:
    """The camera's motion between estimates (95th percentile; one estimate per event frame:
    the motion a frame spans), with a note where a rotation turns too far per frame."""
    line = (f'motion between estimates (95th percentile): turn {turn_deg:.2f} deg, travel '
            f'{100.0 * travel_m:.2f} cm')
    if kind == 'rotation' and turn_deg >= FAST_TURN_DEG:
        line += (f'; at {FAST_TURN_DEG:g} deg or more per frame the network without a gyro '
                 'loses most tracks: fewer events_per_frame or the gyro (docs/demo.md)')
    return line


def run(args: argparse.Namespace) -> int:
    """Evaluate, print, optionally plot."""
    gt = read_groundtruth(args.dataset)
    ef = read_estimate_file(args.estimate)
    est = ef.series
    if not 0 <= args.lag_scan <= 500:
        raise ConfigError(f'--lag-scan {args.lag_scan}: give 0 (off) to 500 ms')
    use = None
    if args.calib_states:
        if ef.state is None:
            raise ConfigError(f'--calib-states: {args.estimate} has no state column (hrn-vo '
                              'run writes one); drop the option for this file')
        use = np.isin(np.asarray(ef.state), args.calib_states)
    res = evaluate(gt, est, args.kind, calib=args.calib, lag_s=args.lag,
                   convention=args.convention, roll_zero_s=args.roll_zero, calib_use=use,
                   lag_window=args.lag_window)
    out = res.to_dict()
    turn, travel = motion_between(gt, est.t)
    out['motion'] = {'turn_deg_p95': round(turn, 4), 'travel_m_p95': round(travel, 6)}
    motion_text = motion_line(args.kind, turn, travel)
    states_text = ''
    if ef.state is not None:
        summary = state_summary(res, est.t, ef.state, int(gt.t[0]))
        out['states'] = summary
        states_text = 'time per state:\n' + format_states(summary, res.series.err_label)
    scan_text = ''
    if args.lag_scan:
        offsets_ms = np.arange(-args.lag_scan, args.lag_scan + 1)
        _, curves = lag_scan(gt, est, args.kind, offsets_ms * 1e-3, calib=args.calib,
                             lag_s=res.lag_s, convention=args.convention,
                             roll_zero_s=args.roll_zero, calib_use=use,
                             lag_window=args.lag_window)
        metric = TARGETS[args.kind][0]
        values = curves[metric]
        best = int(np.argmin(values))
        out['lag_scan'] = {'metric': metric, 'offsets_ms': offsets_ms.tolist(),
                           'values': [round(v, 6) for v in values],
                           'best_offset_ms': int(offsets_ms[best])}
        scan_text = (f'lag scan ({metric}): {values[args.lag_scan]:.4g} at the protocol lag, '
                     f'lowest {values[best]:.4g} at {int(offsets_ms[best]):+d} ms from it')
    plot = None
    if args.plot is not None:
        from hrn_vo_ros.io.plots import plot_evaluation
        plot = plot_evaluation(res, args.plot,
                               title=f'{args.estimate.name} on {args.dataset.name}',
                               states=(sample_states(res, est.t, ef.state, int(gt.t[0]))
                                       if ef.state is not None else None))
    if not args.json:
        echo(format_table(res))
        echo(motion_text)
        if states_text:
            echo(states_text)
        if scan_text:
            echo(scan_text)
        if plot is not None:
            echo(f'plot: {plot}')
    echo(json.dumps(out))
    return 0
