"""The paper's evaluation protocol (its Methods section, "Evaluation"): :func:`evaluate`.

Public API (defined in the modules named, importable from here)::

    EstimateSeries(t, h, v, r, z=None)   # raw readouts: t ns, h/v map px, r rad, z log scale
    evaluate(gt, est, kind, *, calib='last10', lag_s=None, max_lag_s=0.5,
             convention='swing-twist', roll_zero_s=0.1, calib_use=None,
             lag_window='run') -> EvalResult
    lag_scan(gt, est, kind, offsets_s, *, calib='last10', lag_s=None,
             convention='swing-twist', roll_zero_s=0.1, calib_use=None, lag_window='run')
        -> (lag_s, {metric: [..]})
    umeyama(src, dst, *, with_scale=True, allow_reflection=False) -> (s, R, t)  # alignment
    estimate_lag(t_est, sig_est, t_gt, sig_gt, *, rate_hz=400, max_lag_s=0.5)  # lag
    relative_position_errors(p_gt, R_gt, p_est, R_est, lengths)               # metrics
    rotation_metrics / translation_metrics / arm_metrics (samples, calib, test)  # metrics

Modules: :mod:`~hrn_vo_ros.core.evaluation.series` (types, constants),
:mod:`~hrn_vo_ros.core.evaluation.lag`, :mod:`~hrn_vo_ros.core.evaluation.samples` (ground
truth at the estimate times, rotation conventions, roll zeroing),
:mod:`~hrn_vo_ros.core.evaluation.alignment` (Umeyama), :mod:`~hrn_vo_ros.core.evaluation.metrics`
(one function per kind).

Protocol, step by step (all kinds):

1. **Lag.** The ground truth and the estimate are resampled to a fixed 400 Hz grid by linear
   interpolation and cross-correlated (Pearson correlation per lag, lags within ±``max_lag_s``,
   parabolic sub-sample refinement). The signal is the **roll** (rotation, arm); for
   translation it is the sum of squared correlations of (h, v) with the ground-truth x and y (the
   roll is small there). ``lag_s > 0`` means the estimate lags the ground truth; estimate times
   are shifted by ``-lag_s``. A negative roll correlation is reported as a warning (wrong sign).
   The search covers the whole run; ``lag_window='training'`` (not the protocol) searches only
   the part before the evaluated one, which nothing evaluated then fits.
2. **Ground truth at the estimate times** (linear interpolation of positions, geodesic
   interpolation of rotations); estimates outside the ground truth are dropped.
   Everything is expressed relative to the ground-truth pose at the first estimate time t0:
   ``R_rel(t) = R_gt(t0)^T R_gt(t)`` and ``q(t) = R_gt(t0)^T (p_gt(t) - p_gt(t0))`` (first
   camera frame: x right, y down, z forward).
3. **Split** (the "novel split" of the shapes sequences, by line order rather than by time):
   the first 70 % of the ground-truth *lines* are the training part, the rest the test part;
   ``split = gt.t[int(0.7 n_gt)]``.
4. **Calibration** (fixed, fitted once): Umeyama similarity of (h, v) to the target on the
   calibration segment; reflections are allowed because the sign convention of the network's
   image axes is arbitrary (``calibration['reflected']`` says whether one was used).

   * rotation: target (pan, tilt) of ``R_rel`` in the rotation convention
     (:mod:`~hrn_vo_ros.core.evaluation.samples`); segment: the last 10 s of the training part
     (``calib='last10'``, the paper's main results) or all of it (``'full'``);
   * translation: target (x, y) of ``q`` on the whole training part (the paper's choice for
     shapes_translation: too little z motion otherwise), plus the depth model
     ``q_z ≈ a + b exp(k z)`` (k found by a 1-D search, a and b by least squares; the scale
     state z is a log magnification, depth ∝ exp(-z));
   * arm: target (x, y) of ``q`` on the first arc, 0.5–5 s after the start of the ground truth.

   The roll is **not calibrated**, only zeroed at the start: ``roll_est = r - offset`` with
   ``offset = median(r - roll_gt)`` over the first 0.1 s of estimates (the network's roll is an
   absolute angle like the ground truth's). ``roll_zero_s`` lengthens that window as a
   diagnostic (not the protocol): at a slow start the first 0.1 s hold only 3–4 long event
   packets, and their noise moves every later roll error by the same amount.
5. **Errors** on the test 30 % (rotation, translation) or on everything after the first arc
   (arm), by :data:`~hrn_vo_ros.core.evaluation.metrics.KIND_METRICS`:

   * rotation: geodesic angle between ``R_rel`` and ``R_est`` built from the calibrated
     pan/tilt and the zeroed roll in the rotation convention; median in degrees (the paper's
     metric);
   * translation: ``|p_est - q|`` (m), median; relative position error in % of distance
     travelled (the relative error of the rpg_trajectory_evaluation toolbox): the test part is
     aligned with sim(3) (Umeyama, all poses), sub-trajectories of 10, 20, 30, 40, 50 % of the
     test path length start at every pose, error ``|R_est,i^T (p_est,j - p_est,i) -
     R_gt,i^T (p_gt,j - p_gt,i)| / L``; reported: the median over all sub-trajectories and
     lengths (``rel_pos_pct``) and the mean of the per-length medians
     (``rel_pos_pct_mean_of_medians``). The estimated orientation is ``Rz(roll)`` (pan/tilt are
     not estimated);
   * arm: ``|p_est - q|`` with p_est = (x, y, 0) (the estimate has no height), median in metres,
     and the median absolute roll error in degrees.

Bad inputs (missing columns, fewer than 20 estimates, unsorted times, no time overlap, a
calibration segment without samples) raise :class:`~hrn_vo_ros.errors.DatasetError` saying what
to change.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.evaluation.alignment import umeyama
from hrn_vo_ros.core.evaluation.lag import estimate_lag, protocol_lag
from hrn_vo_ros.core.evaluation.metrics import (
    arm_metrics,
    KIND_METRICS,
    relative_position_errors,
    rotation_metrics,
    translation_metrics,
)
from hrn_vo_ros.core.evaluation.samples import (
    align_samples,
    GroundTruthArrays,
    roll_correlation,
    ROTATION_CONVENTIONS,
)
from hrn_vo_ros.core.evaluation.series import (
    ARM_FIRST_ARC_S,
    CALIB_MODES,
    EstimateSeries,
    EVAL_KINDS,
    EvalKind,
    EvalResult,
    EvalSeries,
    F64,
    LAG_WINDOWS,
    MIN_SAMPLES,
    TRAIN_FRACTION,
)
from hrn_vo_ros.core.events.sequence import Trajectory
from hrn_vo_ros.errors import ConfigError, DatasetError

__all__ = [
    'CALIB_MODES',
    'EVAL_KINDS',
    'LAG_WINDOWS',
    'MIN_SAMPLES',
    'ROTATION_CONVENTIONS',
    'TRAIN_FRACTION',
    'EstimateSeries',
    'EvalKind',
    'EvalResult',
    'EvalSeries',
    'arm_metrics',
    'check_inputs',
    'estimate_lag',
    'evaluate',
    'lag_scan',
    'relative_position_errors',
    'rotation_metrics',
    'translation_metrics',
    'umeyama',
]


def evaluate(gt: Trajectory, est: EstimateSeries, kind: str, *, calib: str = 'last10',
             lag_s: float | None = None, max_lag_s: float = 0.5,
             convention: str = 'swing-twist', roll_zero_s: float = 0.1,
             calib_use: NDArray[np.bool_] | None = None,
             lag_window: str = 'run') -> EvalResult:
    """Evaluate a raw estimate against the ground truth with the paper's protocol.

    Args:
        gt: Ground-truth camera poses (camera-to-world), time-ordered.
        est: Raw readouts (h, v, r[, z]) of the network or the baseline.
        kind: ``'rotation'``, ``'translation'`` or ``'arm'``.
        calib: ``'last10'`` (last 10 s of the training part) or ``'full'`` (rotation only; the
            other kinds have fixed calibration segments, see the module docstring).
        lag_s: Use this lag instead of estimating it (seconds, + = estimate lags).
        max_lag_s: Largest lag searched.
        convention: ``'swing-twist'`` or ``'euler'`` pan/tilt/roll
            (:mod:`~hrn_vo_ros.core.evaluation.samples`).
        roll_zero_s: The roll is zeroed on the estimates of the first ``roll_zero_s`` seconds
            (0.1: the protocol; longer only as a diagnostic).
        calib_use: One flag per estimate: only flagged estimates of the calibration segment
            fit the calibration (None: all, the protocol). A diagnostic, not the protocol:
            flagging the estimates the estimator reported as ``tracking`` asks whether its
            claims agree with one calibration when its lost output would distort the
            protocol's fit.
        lag_window: ``'run'`` (the protocol: the lag is searched over the whole run) or
            ``'training'``: only over the part before the evaluated one (the training part;
            for the arm, up to the end of the first arc), so that nothing of the evaluated
            part fits the lag, as nothing of it fits the calibration; one late jump of the
            roll then cannot move the lag of the whole run.

    Returns:
        The metrics, calibration, lag, counts, warnings and aligned series.

    Raises:
        DatasetError: on bad or insufficient inputs (see the module docstring).
        ConfigError: on an unknown kind or calibration mode.
    """
    check_inputs(gt, est, kind, calib, convention)
    if lag_window not in LAG_WINDOWS:
        raise ConfigError(f'lag_window = {lag_window!r}: use one of {", ".join(LAG_WINDOWS)}')
    if not 0.0 < roll_zero_s < 1e3:
        raise ConfigError(f'roll_zero_s = {roll_zero_s}: give the roll zeroing window in seconds '
                          '(> 0; the protocol uses 0.1)')
    warnings: list[str] = []
    g = GroundTruthArrays.from_trajectory(gt, convention)
    t_raw = est.t.astype(np.float64) * 1e-9
    split = float(g.t[int(TRAIN_FRACTION * len(g.t))])
    # 1. lag, and the estimates inside the ground truth once it is corrected
    lag = _lag(kind, t_raw, est, g, lag_s, max_lag_s, warnings,
               None if lag_window == 'run' else _training_end(kind, float(g.t[0]), split))
    t, inside = _inside_ground_truth(t_raw - lag, g, lag, warnings)
    # 2. ground truth at the estimate times, relative to the pose at t0; roll zeroed
    samples = align_samples(g, t, est, inside, convention=convention, roll_zero_s=roll_zero_s)
    roll_corr = roll_correlation(t, samples.r, g)
    _roll_warnings(kind, roll_corr, warnings)
    # 3. split by ground-truth line order, calibration segment and evaluated part
    calib_mask, test, cal_name = _segments(kind, calib, t, float(g.t[0]), split, warnings)
    if calib_use is not None:
        calib_mask, cal_name = _restrict(calib_mask, cal_name, calib_use, inside)
    cal_info: dict[str, float | bool | str] = {'roll_offset_rad': samples.roll_offset,
                                               'roll_zero_s': roll_zero_s,
                                               'lag_window': lag_window,
                                               'convention': convention, 'segment': cal_name}
    # 4./5. calibration and errors, per kind
    res = KIND_METRICS[kind](samples, calib_mask, test)
    cal_info.update(res.calibration)
    warnings.extend(res.warnings)
    series = EvalSeries(t - g.t[0], res.gt_plot, res.est_plot, res.err, calib_mask, test,
                        res.labels, res.units, res.err_label)
    counts = {'estimates': len(est), 'used': len(t), 'calibration': int(calib_mask.sum()),
              'evaluated': int(test.sum())}
    return EvalResult(kind, calib, lag, roll_corr, res.metrics, cal_info, counts, split - g.t[0],
                      tuple(warnings), series)


def lag_scan(gt: Trajectory, est: EstimateSeries, kind: str, offsets_s: F64, *,
             calib: str = 'last10', lag_s: float | None = None,
             max_lag_s: float = 0.5, convention: str = 'swing-twist',
             roll_zero_s: float = 0.1, calib_use: NDArray[np.bool_] | None = None,
             lag_window: str = 'run') -> tuple[float, dict[str, list[float]]]:
    """Every metric with the time alignment moved by each offset (a diagnostic, not the
    protocol): how steeply the errors depend on the lag, and which lag each metric prefers.

    The protocol aligns time by the roll; a position that lags the roll by a few ms (e.g. the
    arm, where ±4 ms move the median position error by ~30 %) shows up as a position minimum
    away from offset 0.

    Args:
        gt, est, kind, calib, max_lag_s, convention, roll_zero_s, calib_use, lag_window: as
            for :func:`evaluate`.
        offsets_s: Offsets added to the lag, seconds (+ = the estimate lags more).
        lag_s: The lag the offsets are added to (None: estimated as :func:`evaluate` does).

    Returns:
        The base lag (s) and, per metric, its value at each offset.

    Raises:
        ConfigError: for non-finite offsets. DatasetError: as :func:`evaluate`.
    """
    offsets = np.asarray(offsets_s, dtype=np.float64).ravel()
    if offsets.size == 0 or not np.all(np.isfinite(offsets)):
        raise ConfigError('lag_scan needs at least one finite offset (seconds)')
    base = (evaluate(gt, est, kind, calib=calib, max_lag_s=max_lag_s, convention=convention,
                     roll_zero_s=roll_zero_s, calib_use=calib_use,
                     lag_window=lag_window).lag_s
            if lag_s is None else float(lag_s))
    curves: dict[str, list[float]] = {}
    for d in offsets:
        res = evaluate(gt, est, kind, calib=calib, lag_s=base + float(d),
                       convention=convention, roll_zero_s=roll_zero_s, calib_use=calib_use)
        for name, value in res.metrics.items():
            curves.setdefault(name, []).append(float(value))
    return base, curves


def check_inputs(gt: Trajectory, est: EstimateSeries, kind: str, calib: str,
                 convention: str) -> None:
    """Refuse unknown options and unusable inputs with a message saying what to change.

    Raises:
        ConfigError: for an unknown kind, rotation convention or calibration mode.
        DatasetError: for missing or non-finite columns, too few samples, unsorted times or no
            time overlap.
    """
    if kind not in EVAL_KINDS:
        raise ConfigError(f'unknown evaluation kind {kind!r}; use one of {", ".join(EVAL_KINDS)}')
    if convention not in ROTATION_CONVENTIONS:
        raise ConfigError(f'unknown rotation convention {convention!r}; use one of '
                          f'{", ".join(ROTATION_CONVENTIONS)}')
    if calib not in CALIB_MODES:
        raise ConfigError(f'unknown calibration mode {calib!r}; use one of '
                          f'{", ".join(CALIB_MODES)}')
    n = len(est)
    for name in ('h', 'v', 'r'):
        arr = getattr(est, name)
        if arr is None or arr.shape != (n,):
            raise DatasetError(f'estimate column {name!r} is missing or has the wrong length '
                               f'(expected {n} values)')
        if not np.all(np.isfinite(arr)):
            raise DatasetError(f'estimate column {name!r} contains NaN or infinite values')
        if arr.size and float(np.max(np.abs(arr))) > MAX_ABS_ESTIMATE:
            k = int(np.argmax(np.abs(arr)))
            raise DatasetError(f'estimate column {name!r} holds {float(arr[k]):g} (row {k + 2}): '
                               f'values beyond {MAX_ABS_ESTIMATE:g} are corrupt, not readouts; '
                               'fix or regenerate the estimate file')
    if est.z is not None and est.z.shape != (n,):
        raise DatasetError(f'estimate column z has {est.z.shape[0]} values, expected {n}')
    if est.z is not None and est.z.size and not (
            np.all(np.isfinite(est.z)) and float(np.max(np.abs(est.z))) <= MAX_ABS_ESTIMATE):
        raise DatasetError(f'estimate column z holds NaN, infinite or values beyond '
                           f'{MAX_ABS_ESTIMATE:g}: fix or regenerate the estimate file')
    _check_ground_truth(gt)
    if n < MIN_SAMPLES:
        raise DatasetError(f'only {n} estimates: the evaluation needs at least {MIN_SAMPLES} '
                           '(run on a longer sequence)')
    if np.any(np.diff(est.t) <= 0):
        k = int(np.flatnonzero(np.diff(est.t) <= 0)[0])
        raise DatasetError(f'estimate times are not strictly increasing (row {k + 2}: '
                           f'{est.t[k + 1] * 1e-9:.9f} s after {est.t[k] * 1e-9:.9f} s)')
    if len(gt) < MIN_SAMPLES:
        raise DatasetError(f'only {len(gt)} ground-truth poses: need at least {MIN_SAMPLES}')
    if np.any(np.diff(gt.t) <= 0):
        raise DatasetError('ground-truth times are not strictly increasing')
    if est.t[-1] <= gt.t[0] or est.t[0] >= gt.t[-1]:
        raise DatasetError(f'no time overlap: estimates span {est.t[0] * 1e-9:.3f}–'
                           f'{est.t[-1] * 1e-9:.3f} s, ground truth {gt.t[0] * 1e-9:.3f}–'
                           f'{gt.t[-1] * 1e-9:.3f} s (same clock? right dataset?)')


MAX_ABS_ESTIMATE = 1e9
"""Largest readout magnitude :func:`check_inputs` accepts (map pixels, radians, log scale)."""
MAX_ABS_GT_POSITION = 1e7
"""Largest ground-truth coordinate (m) :func:`check_inputs` accepts."""


def _check_ground_truth(gt: Trajectory) -> None:
    """Refuse ground truth with non-finite or absurd positions or non-unit quaternions.

    Raises:
        DatasetError: naming the first bad pose (0-based index and time).
    """
    pos = np.asarray(gt.pos, np.float64)
    quat = np.asarray(gt.quat, np.float64)
    n = len(gt)
    if pos.shape != (n, 3) or quat.shape != (n, 4):
        raise DatasetError(f'ground truth needs (n, 3) positions and (n, 4) quaternions; got '
                           f'{pos.shape} and {quat.shape} for {n} times')
    with np.errstate(over='ignore', invalid='ignore'):
        norm = np.linalg.norm(quat, axis=1)
        bad_pos = ~np.all(np.isfinite(pos) & (np.abs(pos) <= MAX_ABS_GT_POSITION), axis=1)
    bad_q = ~(np.abs(norm - 1.0) <= 0.1)
    bad = np.flatnonzero(bad_pos | bad_q)
    if bad.size:
        k = int(bad[0])
        what = (f'position {pos[k].tolist()} is not finite or beyond {MAX_ABS_GT_POSITION:g} m'
                if bad_pos[k] else f'quaternion {quat[k].tolist()} is not a unit quaternion')
        raise DatasetError(f'ground-truth pose {k} (t = {int(gt.t[k]) * 1e-9:.9f} s): {what}; '
                           'fix or remove that line of the ground truth')


def _training_end(kind: str, t_start: float, split: float) -> float:
    """Where the part before the evaluated one ends (ground-truth seconds): the split, or
    for the arm the end of its first arc (:func:`_segments`)."""
    return t_start + ARM_FIRST_ARC_S if kind == 'arm' else split


def _lag(kind: str, t_raw: F64, est: EstimateSeries, g: GroundTruthArrays,
         lag_s: float | None, max_lag_s: float, warnings: list[str],
         end: float | None = None) -> float:
    """The given lag, or the protocol's estimate (searched in both cases: the search also
    checks that the estimate and the ground truth overlap long enough); ``end``: search only
    the estimates and ground truth before this time (s)."""
    if end is not None:
        e, k = t_raw <= end, g.t <= end
        est = EstimateSeries(est.t[e], est.h[e], est.v[e], est.r[e],
                             None if est.z is None else est.z[e])
        t_raw, g = t_raw[e], replace(g, t=g.t[k], R=g.R[k], p=g.p[k], roll=g.roll[k])
    lag_found = protocol_lag(kind, t_raw, est, g.t, g.R, g.p, g.roll, max_lag_s=max_lag_s)
    lag = lag_found if lag_s is None else float(lag_s)
    if lag_s is None and abs(abs(lag) - max_lag_s) < 2.5e-3:
        warnings.append(f'the lag {lag:+.3f} s is at the edge of the search range '
                        f'±{max_lag_s} s: the estimate may not follow the ground truth')
    return lag


def _inside_ground_truth(t: F64, g: GroundTruthArrays, lag: float, warnings: list[str],
                         ) -> tuple[F64, NDArray[np.bool_]]:
    """The lag-corrected times inside the ground truth, and the mask that selects them."""
    inside = (t >= g.t[0]) & (t <= g.t[-1])
    if int(inside.sum()) < MIN_SAMPLES:
        raise DatasetError(f'only {int(inside.sum())} estimates fall inside the ground truth '
                           f'after the lag correction ({lag:+.3f} s)')
    if not np.all(inside):
        warnings.append(f'{int((~inside).sum())} estimates outside the ground-truth time range '
                        'were dropped')
    return t[inside], inside


def _roll_warnings(kind: str, roll_corr: float, warnings: list[str]) -> None:
    """Warn about a flipped roll sign, or (but for translation) a poorly correlated roll."""
    if roll_corr < -0.3:
        warnings.append(f'the roll is anti-correlated with the ground truth (r = {roll_corr:.2f}):'
                        " the estimate's roll sign looks flipped")
    elif kind != 'translation' and roll_corr < 0.5:
        warnings.append(f'the roll correlates poorly with the ground truth (r = {roll_corr:.2f})')


def _restrict(calib_mask: NDArray[np.bool_], cal_name: str, use: NDArray[np.bool_],
              inside: NDArray[np.bool_]) -> tuple[NDArray[np.bool_], str]:
    """The calibration mask keeping only the estimates ``use`` flags (``evaluate``'s
    ``calib_use``; ``inside`` selects the samples among the estimates).

    Raises:
        DatasetError: when ``use`` does not have one flag per estimate, or fewer than
            :data:`MIN_SAMPLES` flagged estimates remain in the segment.
    """
    use = np.asarray(use)
    if use.dtype != np.bool_ or use.shape != inside.shape:
        raise DatasetError(f'calib_use needs one boolean per estimate ({inside.size}); got '
                           f'{use.dtype} of shape {use.shape}')
    mask = calib_mask & use[inside]
    n = int(mask.sum())
    if n < MIN_SAMPLES:
        raise DatasetError(f'the calibration segment ({cal_name}) holds {n} flagged estimates; '
                           f'need at least {MIN_SAMPLES}')
    return mask, f'{cal_name}, flagged estimates only'


def _segments(kind: str, calib: str, t: F64, t_start: float, split: float,
              warnings: list[str]) -> tuple[NDArray[np.bool_], NDArray[np.bool_], str]:
    """The calibration mask, the evaluated mask and the calibration segment's name.

    Raises:
        DatasetError: when either holds fewer than :data:`MIN_SAMPLES` estimates.
    """
    train = t < split
    test = ~train
    if kind == 'arm':
        calib_mask = (t >= t_start + 0.5) & (t <= t_start + ARM_FIRST_ARC_S)
        test = t > t_start + ARM_FIRST_ARC_S
        arc = f'0.5–{ARM_FIRST_ARC_S:g} s'
        if calib != 'last10':
            warnings.append(f'--calib is ignored for the arm: the first arc ({arc}) is used')
        cal_name = f'first arc {arc}'
    elif kind == 'translation':
        calib_mask = train.copy()
        if calib != 'last10':
            warnings.append('--calib is ignored for translation: the whole training part is used')
        cal_name = 'whole training part'
    elif calib == 'full':
        calib_mask = train.copy()
        cal_name = 'whole training part'
    else:
        calib_mask = train & (t >= split - 10.0)
        cal_name = 'last 10 s of the training part'
        if np.any(train) and float(t[train][0]) > split - 10.0:
            warnings.append('the training part is shorter than 10 s: all of it is used')
    n_cal = int(calib_mask.sum())
    if n_cal < MIN_SAMPLES:
        raise DatasetError(f'the calibration segment ({cal_name}) holds {n_cal} estimates; '
                           f'need at least {MIN_SAMPLES} (is the sequence long enough?)')
    if int(test.sum()) < MIN_SAMPLES:
        raise DatasetError(f'the evaluated part holds {int(test.sum())} estimates; need at '
                           f'least {MIN_SAMPLES} (is the sequence long enough?)')
    return calib_mask, test, cal_name
