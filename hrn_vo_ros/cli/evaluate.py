"""``hrn-vo evaluate DATASET est.csv --kind rotation|translation|arm [--calib last10|full]``.

Evaluates an estimate CSV (``t,h,v,r[,z]``, as ``hrn-vo run`` writes it) against the dataset's
``groundtruth.txt`` with the paper's protocol (:mod:`hrn_vo_ros.core.evaluation`): lag by
cross-correlation, 70/30 split, Umeyama calibration, median errors on the test part. Prints a
table and, last, one JSON line (``--json``: the JSON line only). ``--plot OUT.png`` draws the
calibrated trajectory against the ground truth.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hrn_vo_ros.cli.main import echo
from hrn_vo_ros.core.evaluation import CALIB_MODES, EVAL_KINDS, EvalResult, evaluate
from hrn_vo_ros.io.ecd import read_groundtruth
from hrn_vo_ros.io.estimates import read_estimates

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
    p.add_argument('--lag', type=float, default=None,
                   help='use this lag in seconds instead of estimating it')
    p.add_argument('--plot', type=Path, default=None, help='write a trajectory plot (PNG)')
    p.add_argument('--json', action='store_true', help='print only the JSON line')
    p.set_defaults(func=run)


def format_table(res: EvalResult) -> str:
    """A human-readable table of the result."""
    rows = [('kind', res.kind), ('calibration', str(res.calibration.get('segment', ''))),
            ('lag', f'{res.lag_s * 1e3:+.1f} ms'), ('roll correlation', f'{res.roll_corr:.3f}'),
            ('estimates used / calib / evaluated',
             f'{res.counts["used"]} / {res.counts["calibration"]} / {res.counts["evaluated"]}'),
            ('split at', f'{res.split_s:.2f} s')]
    rows += [(k, f'{v:.4g}') for k, v in res.metrics.items()]
    rows += [('warning', w) for w in res.warnings]
    width = max(len(k) for k, _ in rows)
    return '\n'.join(f'{k:<{width}}  {v}' for k, v in rows)


def run(args: argparse.Namespace) -> int:
    """Evaluate, print, optionally plot."""
    gt = read_groundtruth(args.dataset)
    est = read_estimates(args.estimate)
    res = evaluate(gt, est, args.kind, calib=args.calib, lag_s=args.lag)
    if args.plot is not None:
        from hrn_vo_ros.io.plots import plot_evaluation
        plot_evaluation(res, args.plot, title=f'{args.estimate.name} on {args.dataset.name}')
    if not args.json:
        echo(format_table(res))
        if args.plot is not None:
            echo(f'plot: {args.plot}')
    echo(json.dumps(res.to_dict()))
    return 0
