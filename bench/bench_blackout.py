"""Blackout benchmark: re-localisation after the events stop while the camera turns.

The robust-tracking acceptance asks that after a blackout with at least 30° of motion the track
is re-localised within 50 frames. This measures it on the randomized rotation family
(:mod:`hrn_vo_ros.core.sim.family`, fresh draws 10000 on, ``--tuning`` for 0-99):

1. per draw, the **blackout window** is the first one that starts at or after ``--start`` s
   (0.05 s steps) and, within at most ``--max-window`` s, turns the camera by ``--min-deg``
   (geodesic angle between the ground-truth orientations at its ends); draws without one are
   reported as "no window" and skipped;
2. every event in the window is removed (a lens cap, a dark room, a driver stall; the IMU keeps
   running), the frames are made again with the config's packetizer as ``hrn-vo run`` makes
   them, and each method runs on them (as :mod:`bench_robustness`, same configs and caches);
3. the estimate is evaluated with the paper's protocol, but the lag (roll cross-correlation)
   and the calibration are fitted on the estimates *before* the window only (``evaluate``'s
   ``lag_s`` and ``calib_use``), so that what happens after the blackout does not move them
   (over a whole sequence with a lost stretch the lag search can end at its ±0.5 s edge);
4. per draw and method: **tracked before** (the error below the loss threshold, 10°, over the
   last second before the window; other draws do not count), **re-localised** at the first
   frame after the window from which the error stays below the threshold for 0.5 s, counted
   in frames from the first frame after the window (**within 50 frames** is the target),
   **flagged** (a frame after the window reported ``degraded`` or ``lost`` before the
   re-localisation, or the error did not go above the threshold between the window and the
   re-localisation) and the error at the end.

Examples::

    scripts/run.sh python bench/bench_blackout.py --smoke
    scripts/run.sh python bench/bench_blackout.py -n 60 --methods hrn hrn_imu \
        --cache /tmp/hrn_family --csv build/blackout.csv
"""

from __future__ import annotations

import os

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import argparse  # noqa: E402
import csv  # noqa: E402
from dataclasses import asdict, dataclass  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
from pathlib import Path  # noqa: E402
import pickle  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bench'))

import bench_robustness as robust  # noqa: E402

from hrn_vo_ros.core.evaluation.lag import protocol_lag  # noqa: E402
from hrn_vo_ros.core.evaluation.protocol import EstimateSeries, evaluate  # noqa: E402
from hrn_vo_ros.core.evaluation.samples import GroundTruthArrays  # noqa: E402
from hrn_vo_ros.core.events.frames import frames_from_events  # noqa: E402
from hrn_vo_ros.core.events.packet_config import with_calibration  # noqa: E402
from hrn_vo_ros.core.events.sequence import Sequence, Trajectory  # noqa: E402
from hrn_vo_ros.core.odometry.geometry import (  # noqa: E402
    matrix_to_swing_twist,
    quat_to_matrix,
    rotation_angle,
)
from hrn_vo_ros.core.sim.family import draw, fresh_seeds, simulate_draw, tuning_seeds  # noqa: E402
from hrn_vo_ros.errors import DatasetError  # noqa: E402

KIND = 'rotation'
METHODS = ('hrn', 'hrn_imu', 'spiking')
TARGET_FRAMES = 50     # re-localised within this many frames after the window
BEFORE_S = 1.0         # tracked before: the error below the threshold over this long


@dataclass
class Row:
    """One method on one draw with a blackout."""

    seed: int
    method: str
    start_s: float        # window start, s from the first ground-truth pose
    length_s: float       # window length, s
    turn_deg: float       # camera turn over the window, deg
    roll_deg: float       # of which roll about the optical axis (swing-twist), deg
    removed: int          # events removed
    before: bool          # tracked over the last second before the window
    reloc_frames: int     # frames from the first frame after the window; -1: never
    reloc_s: float        # the same in seconds (nan: never)
    flagged: bool         # degraded / lost reported before re-localising (or no loss at all)
    end_err_deg: float    # error at the last sample
    note: str


def window(gt: Trajectory, start_s: float, max_s: float, min_deg: float
           ) -> tuple[float, float, float, float] | None:
    """The first blackout window (start s, length s, turn deg, of which roll deg) from
    ``start_s`` on (module docstring, step 1), times from the first ground-truth pose; None if
    there is none. The roll part is the twist about the optical axis (swing-twist): a turn that
    is mostly roll keeps the scene in view, a pan or tilt moves it towards the map's edge."""
    t = (gt.t - gt.t[0]) * 1e-9
    R = quat_to_matrix(gt.quat)
    for s in np.arange(start_s, t[-1] - max_s - 2.0, 0.05):
        i = int(np.searchsorted(t, s))
        j_end = int(np.searchsorted(t, s + max_s))
        turn = rotation_angle(np.swapaxes(R[i:i + 1], 1, 2) @ R[i:j_end]) * (180 / np.pi)
        hit = np.flatnonzero(turn >= min_deg)
        if hit.size:
            j = i + int(hit[0])
            _, _, roll = matrix_to_swing_twist(R[i].T @ R[j])
            return (float(t[i]), float(t[j] - t[i]), float(turn[hit[0]]),
                    abs(float(roll)) * (180 / np.pi))
    return None


def _sequence(seed: int, seconds: float, cache: str) -> Sequence:
    """The draw's full sequence (events included), from ``bench_robustness``'s cache."""
    raw = Path(cache) / f'{KIND}_{seed}_{seconds:g}_events.pkl' if cache else None
    if raw is not None and raw.exists():
        with open(raw, 'rb') as f:
            seq: Sequence = pickle.load(f)
            return seq
    seq = simulate_draw(draw(KIND, seed), seconds)
    if raw is not None:
        raw.parent.mkdir(parents=True, exist_ok=True)
        with open(raw, 'wb') as f:
            pickle.dump(seq, f)
    return seq


def job(task: tuple[int, float, tuple[str, ...], str, float, float, float]) -> list[Row]:
    """One draw: find the window, remove its events, run and judge every method."""
    seed, seconds, methods, cache, start_s, max_s, min_deg = task
    seq = _sequence(seed, seconds, cache)
    gt = seq.groundtruth
    assert gt is not None
    win = window(gt, start_s, max_s, min_deg)
    if win is None:
        return [Row(seed, m, math.nan, math.nan, math.nan, math.nan, 0, False, -1, math.nan,
                    False, math.nan, 'no window') for m in methods]
    s0, length = win[:2]
    a = int(gt.t[0] + s0 * 1e9)
    b = int(gt.t[0] + (s0 + length) * 1e9)
    keep = (seq.events.t < a) | (seq.events.t >= b)
    cut = Sequence(seq.events[keep], seq.calib, seq.imu, gt)
    small = Sequence(cut.events[:1], cut.calib, cut.imu, gt)
    framings: dict[bool, tuple[np.ndarray, np.ndarray]] = {}
    gyro_packets = robust.imu_framing(KIND)
    rows = []
    for method in methods:
        imu = method == 'hrn_imu' and gyro_packets   # the packets of a fused gyro
        if imu not in framings:
            pcfg, _ = robust._configs(KIND, cut, imu)
            if pcfg.rectify != 'none':
                pcfg = with_calibration(pcfg, cut.calib)
            framings[imu] = frames_from_events(cut.events, pcfg)
        t, imgs = framings[imu]
        rows.append(_judge(seed, method, small, t, imgs, win, int((~keep).sum())))
    return rows


def _judge(seed: int, method: str, seq: Sequence, t: np.ndarray, imgs: np.ndarray,
           win: tuple[float, float, float, float], removed: int) -> Row:
    """Run one method on the frames with the blackout and judge its re-localisation."""
    s0, length, turn, roll = win
    gt = seq.groundtruth
    assert gt is not None
    thr = robust.THRESHOLD[KIND]
    tf = (t.astype(np.float64) - float(gt.t[0])) * 1e-9       # frame times, s
    try:
        est, states, _ = robust._run(method, KIND, seq, t, imgs)
        early = (est.t.astype(np.float64) - float(gt.t[0])) * 1e-9 < s0
        g = GroundTruthArrays.from_trajectory(gt, 'swing-twist')
        lag = protocol_lag(KIND, est.t[early].astype(np.float64) * 1e-9, EstimateSeries(
            est.t[early], est.h[early], est.v[early], est.r[early]), g.t, g.R, g.p, g.roll,
            max_lag_s=0.5)
        res = evaluate(gt, est, KIND, lag_s=lag, calib_use=early)
    except DatasetError as exc:
        return Row(seed, method, s0, length, turn, roll, removed, False, -1, math.nan, False,
                   math.nan, f'{type(exc).__name__}: {str(exc)[:80]}')
    ts, err = res.series.t_s, res.series.err
    # the frame behind each evaluated sample (its time minus the lag, nearest)
    idx = np.clip(np.searchsorted(tf, ts + res.lag_s), 0, len(tf) - 1)
    pre = (ts >= s0 - BEFORE_S) & (ts < s0)
    before = bool(pre.any() and np.all(err[pre] <= thr))
    after = np.flatnonzero(ts >= s0 + length)
    first_frame = int(np.searchsorted(tf, s0 + length))
    reloc = -1
    bad = err > thr
    for k in after:          # the first good sample before RECOVER_S without a bad one
        if bad[k]:
            continue
        later = np.flatnonzero(bad[k:])
        until = ts[k + int(later[0])] if later.size else ts[-1]
        if until - ts[k] >= robust.RECOVER_S:
            reloc = int(k)
            break
    st = np.asarray(states) if states is not None else None
    end = int(idx[reloc]) if reloc >= 0 else len(tf)
    gap = after[ts[after] < ts[reloc]] if reloc >= 0 else after   # window end .. re-lock
    bad_after = bool(np.any(bad[gap]))
    flagged = (not bad_after) or (st is not None and bool(
        np.any(st[first_frame:end] != 'tracking')))
    frames = int(idx[reloc]) - first_frame if reloc >= 0 else -1
    if reloc < 0:
        return Row(seed, method, s0, length, turn, roll, removed, before, -1, math.nan,
                   flagged, float(err[-1]), '')
    return Row(seed, method, s0, length, turn, roll, removed, before, max(frames, 0),
               float(ts[reloc] - (s0 + length)), flagged, float(err[-1]), '')


def _describe(r: Row) -> str:
    """One method's outcome on one draw, for the progress lines."""
    if r.note:
        return r.note
    if not r.before:
        return 'not tracked before'
    if r.reloc_frames < 0:
        return f'never (end {r.end_err_deg:.1f} deg)'
    return (f'{r.reloc_frames} frames / {r.reloc_s:.2f} s'
            + ('' if r.flagged else ', unflagged'))


def summary(rows: list[Row], methods: list[str]) -> list[str]:
    """Per method: draws with a window, tracked before, re-localised within the target."""
    lines = [f'{"method":9s} {"window":>7s} {"before":>7s} {"<=50 fr":>8s} {"later":>6s} '
             f'{"never":>6s} {"median fr":>9s} {"median s":>8s} {"unflagged":>9s}']
    for m in methods:
        rs = [r for r in rows if r.method == m]
        win = [r for r in rs if r.note != 'no window']
        pre = [r for r in win if r.before]
        ok = [r for r in pre if 0 <= r.reloc_frames <= TARGET_FRAMES]
        late = [r for r in pre if r.reloc_frames > TARGET_FRAMES]
        never = [r for r in pre if r.reloc_frames < 0]
        got = [r for r in pre if r.reloc_frames >= 0]
        fr = f'{np.median([r.reloc_frames for r in got]):.0f}' if got else '-'
        sec = f'{np.median([r.reloc_s for r in got]):.2f}' if got else '-'
        lines.append(f'{m:9s} {len(win):>3d}/{len(rs):<3d} {len(pre):>7d} '
                     f'{len(ok):>4d}/{len(pre):<3d} {len(late):>6d} {len(never):>6d} '
                     f'{fr:>9s} {sec:>8s} {sum(not r.flagged for r in pre):>9d}')
    return lines


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; returns 0 (figures are printed, not asserted)."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--methods', nargs='+', choices=METHODS, default=['hrn', 'hrn_imu'])
    p.add_argument('-n', type=int, default=30, help='draws (default 30)')
    p.add_argument('--seeds', type=int, nargs='+', default=None,
                   help='run these seeds instead of the first -n of the split')
    p.add_argument('--tuning', action='store_true',
                   help='use the tuning draws (seeds 0-99) instead of the fresh ones (10000+)')
    p.add_argument('--seconds', type=float, default=10.0, help='per sequence (default 10)')
    p.add_argument('--start', type=float, default=3.0,
                   help='earliest window start, s (default 3)')
    p.add_argument('--max-window', type=float, default=2.0,
                   help='longest blackout, s (default 2)')
    p.add_argument('--min-deg', type=float, default=30.0,
                   help='camera turn the blackout must span, deg (default 30)')
    p.add_argument('--jobs', type=int, default=os.cpu_count() or 1, help='worker processes')
    p.add_argument('--cache', type=Path, default=None,
                   help="keep the simulated events here (bench_robustness's cache)")
    p.add_argument('--csv', type=Path, default=None, help='write the per-draw rows here')
    p.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                   help='override a resonator setting (as bench_robustness --set; repeatable)')
    p.add_argument('--smoke', action='store_true',
                   help='tiny run: one draw, 7 s, a window from 3 s of at most 1 s and 10 deg')
    args = p.parse_args(argv)
    if args.smoke:
        args.n, args.seconds, args.seeds = 1, 7.0, None
        args.start, args.max_window, args.min_deg = 3.0, 1.0, 10.0
    for name, value, low in (('--seconds', args.seconds, 4.0), ('--max-window',
                                                                 args.max_window, 0.05),
                             ('--min-deg', args.min_deg, 1.0), ('-n', args.n, 1)):
        if not value >= low:
            print(f'{name} {value}: give at least {low:g}', file=sys.stderr)
            return 2
    if args.csv is not None and not args.csv.parent.is_dir():
        print(f'--csv: the folder {args.csv.parent} does not exist', file=sys.stderr)
        return 2
    seeds = args.seeds or (tuning_seeds(args.n) if args.tuning else fresh_seeds(args.n))
    cache = '' if args.cache is None else str(args.cache)
    tasks = [(s, args.seconds, tuple(args.methods), cache, args.start, args.max_window,
              args.min_deg) for s in seeds]
    print(f'{len(tasks)} rotation draws ({"tuning" if args.tuning else "fresh"}, '
          f'{args.seconds:g} s), blackout: the first window from {args.start:g} s of at most '
          f'{args.max_window:g} s turning >= {args.min_deg:g} deg; methods '
          f'{", ".join(args.methods)}, {args.jobs} jobs', flush=True)
    t0 = time.perf_counter()
    rows: list[Row] = []
    ctx = multiprocessing.get_context('spawn')
    over = {k.strip(): robust._value(v.strip())
            for k, _, v in (item.partition('=') for item in args.set)}
    with ctx.Pool(args.jobs, robust._init, (over, {}, {})) as pool:
        for out in pool.imap_unordered(job, tasks):
            rows += out
            r0 = out[0]
            head = (f'  {r0.seed}: no window' if r0.note == 'no window' else
                    f'  {r0.seed}: {r0.start_s:.2f}-{r0.start_s + r0.length_s:.2f} s, '
                    f'{r0.turn_deg:.0f} deg (roll {r0.roll_deg:.0f}), {r0.removed} events '
                    'removed')
            if r0.note != 'no window':
                head += ''.join(f'; {r.method} {_describe(r)}' for r in out)
            print(head, flush=True)
    rows.sort(key=lambda r: (r.seed, r.method))
    print(f'\n{len(tasks)} draws in {time.perf_counter() - t0:.0f} s')
    print(f're-localised: the error (lag and calibration fitted before the window) below '
          f'{robust.THRESHOLD[KIND]:g} deg for {robust.RECOVER_S:g} s; frames counted from '
          f'the first frame after the window; target <= {TARGET_FRAMES} frames')
    for line in summary(rows, list(args.methods)):
        print(line)
    if args.csv is not None:
        with open(args.csv, 'w', newline='') as f:
            w = csv.DictWriter(f, fieldnames=list(asdict(rows[0])))
            w.writeheader()
            for r in rows:
                w.writerow(asdict(r))
        print(f'rows -> {args.csv}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
