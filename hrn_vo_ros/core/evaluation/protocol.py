"""The paper's evaluation protocol (Renner et al., Methods "Evaluation"; hrn_math.md §8).

Public API::

    EstimateSeries(t, h, v, r, z=None)   # raw readouts: t ns, h/v map px, r rad, z log scale
    evaluate(gt, est, kind, *, calib='last10', lag_s=None, max_lag_s=0.5,
             convention='swing-twist', roll_zero_s=0.1) -> EvalResult
    lag_scan(gt, est, kind, offsets_s, *, calib='last10', lag_s=None,
             convention='swing-twist', roll_zero_s=0.1) -> (lag_s, {metric: [..]})
    umeyama(src, dst, *, with_scale=True, allow_reflection=False) -> (s, R, t)  # dst≈sR src+t
    estimate_lag(t_est, sig_est, t_gt, sig_gt, *, rate_hz=400, max_lag_s=0.5) -> (lag_s, corr)
    relative_position_errors(p_gt, R_gt, p_est, R_est, lengths) -> dict[length, errors %]

Protocol, step by step (all kinds):

1. **Lag.** The ground truth and the estimate are resampled to a fixed 400 Hz grid by linear
   interpolation and cross-correlated (Pearson correlation per lag, lags within ±``max_lag_s``,
   parabolic sub-sample refinement). The signal is the **roll** (rotation, arm); for
   translation it is the sum of squared correlations of (h, v) with the ground-truth x and y (the
   roll is small there). ``lag_s > 0`` means the estimate lags the ground truth; estimate times
   are shifted by ``-lag_s``. A negative roll correlation is reported as a warning (wrong sign).
2. **Ground truth at the estimate times** (linear interpolation of positions, geodesic
   interpolation of rotations); estimates outside the ground truth are dropped.
   Everything is expressed relative to the ground-truth pose at the first estimate time t0:
   ``R_rel(t) = R_gt(t0)^T R_gt(t)`` and ``q(t) = R_gt(t0)^T (p_gt(t) - p_gt(t0))`` (first
   camera frame: x right, y down, z forward).
3. **Split** (Nguyen's "novel split"): the first 70 % of the ground-truth *lines* are the
   training part, the rest the test part; ``split = gt.t[int(0.7 n_gt)]``.
4. **Calibration** (fixed, fitted once): Umeyama similarity of (h, v) to the target on the
   calibration segment; reflections are allowed because the sign convention of the network's
   image axes is arbitrary (``calibration['reflected']`` says whether one was used).

   * rotation: target (pan, tilt) of ``R_rel`` in the rotation convention (below); segment:
     the last 10 s of the training part
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
   (arm):

   * rotation: geodesic angle between ``R_rel`` and ``R_est`` built from the calibrated
     pan/tilt and the zeroed roll in the rotation convention; median in degrees (the paper's
     metric);
   * translation: ``|p_est - q|`` (m), median; relative position error in % of distance
     travelled (rpg_trajectory_evaluation, Zhang & Scaramuzza 2018): the test part is aligned
     with sim(3) (Umeyama, all poses), sub-trajectories of 10, 20, 30, 40, 50 % of the test path
     length start at every pose, error ``|R_est,i^T (p_est,j - p_est,i) - R_gt,i^T (p_gt,j -
     p_gt,i)| / L``; reported: the median over all sub-trajectories and lengths
     (``rel_pos_pct``) and the mean of the per-length medians (``rel_pos_pct_mean_of_medians``).
     The estimated orientation is ``Rz(roll)`` (pan/tilt are not estimated);
   * arm: ``|p_est - q|`` with p_est = (x, y, 0) (the estimate has no height), median in metres,
     and the median absolute roll error in degrees.

**Rotation convention** (stated here; `core.odometry.geometry`).
Pan, tilt and roll (of the ground truth, and of the estimate when it is turned back into a
rotation) are **swing-twist** angles by default, ``R = exp([tilt, pan, 0]^) Rz(roll)``: the
swing points the optical axis, the twist turns the camera about it. This is what an estimator
of an image shift and of an image rotation about the image centre measures (after the
equidistant rectification the shift is the swing angle times the focal length, and the image
turns by the twist at its centre). ``convention='euler'`` uses ``R = Ry(pan) Rx(tilt)
Rz(roll)`` instead, whose roll carries an extra twist of about ``-pan * tilt / 2`` that no
image-plane estimator sees (0.3° at pan = tilt = 6°). The roll used for the lag and the
zeroing follows the same convention. The geodesic error of a perfect estimate is zero in its
own convention; the conventions agree to first order.

Bad inputs (missing columns, fewer than 20 estimates, unsorted times, no time overlap, a
calibration segment without samples) raise :class:`~hrn_vo_ros.errors.DatasetError` saying what
to change.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrn_vo_ros.core.events.sequence import Trajectory
from hrn_vo_ros.core.odometry.geometry import (
    euler_ptr_to_matrix,
    matrix_to_euler_ptr,
    matrix_to_swing_twist,
    quat_to_matrix,
    rot_z,
    rotation_angle,
    so3_exp,
    so3_log,
    swing_twist_to_matrix,
)
from hrn_vo_ros.errors import ConfigError, DatasetError

F64 = NDArray[np.float64]
EvalKind = Literal['rotation', 'translation', 'arm']
EVAL_KINDS = ('rotation', 'translation', 'arm')
CALIB_MODES = ('last10', 'full')
# rotation convention -> (R -> (pan, tilt, roll), (pan, tilt, roll) -> R); module docstring
_CONVENTIONS: dict[str, tuple[Callable[[F64], tuple[F64, F64, F64]],
                              Callable[[ArrayLike, ArrayLike, ArrayLike], F64]]] = {
    'swing-twist': (matrix_to_swing_twist, swing_twist_to_matrix),
    'euler': (matrix_to_euler_ptr, euler_ptr_to_matrix),
}
ROTATION_CONVENTIONS = tuple(_CONVENTIONS)
MIN_SAMPLES = 20
TRAIN_FRACTION = 0.7
RPG_FRACTIONS = (0.1, 0.2, 0.3, 0.4, 0.5)


@dataclass(frozen=True, slots=True, eq=False)
class EstimateSeries:
    """Raw network (or baseline) readouts, one row per event frame.

    Shapes:
        t: (n,) int64 ns, sensor clock (packet midpoints); h, v: (n,) map pixels;
        r: (n,) roll in radians; z: (n,) log scale or None.
    """

    t: NDArray[np.int64]
    h: F64
    v: F64
    r: F64
    z: F64 | None = None

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True, slots=True, eq=False)
class EvalSeries:
    """Aligned, calibrated series for plots (float seconds from the first ground-truth pose).

    Shapes:
        t_s: (n,); gt, est: (n, 3) in ``units``; err: (n,) per-sample error; calib, test: (n,)
        masks of the calibration segment and of the evaluated samples.
    """

    t_s: F64
    gt: F64
    est: F64
    err: F64
    calib: NDArray[np.bool_]
    test: NDArray[np.bool_]
    labels: tuple[str, str, str]
    units: tuple[str, str, str]
    err_label: str


@dataclass(frozen=True, slots=True, eq=False)
class EvalResult:
    """Outcome of :func:`evaluate`: the headline metrics and everything needed to check them."""

    kind: str
    calib_mode: str
    lag_s: float
    roll_corr: float
    metrics: dict[str, float]
    calibration: dict[str, float | bool | str]
    counts: dict[str, int]
    split_s: float
    warnings: tuple[str, ...]
    series: EvalSeries = field(repr=False)

    def to_dict(self) -> dict[str, object]:
        """A JSON-able summary (no per-sample series)."""
        return {'kind': self.kind, 'calib': self.calib_mode, 'lag_s': round(float(self.lag_s), 6),
                'roll_corr': round(self.roll_corr, 4),
                'metrics': {k: round(v, 6) for k, v in self.metrics.items()},
                'calibration': self.calibration, 'counts': self.counts,
                'split_s': round(float(self.split_s), 3), 'warnings': list(self.warnings)}


# ------------------------------------------------------------------------------------------
# Umeyama


def umeyama(src: F64, dst: F64, *, with_scale: bool = True,
            allow_reflection: bool = False) -> tuple[float, F64, F64]:
    """Least-squares similarity ``dst ≈ s R src + t`` (Umeyama 1991, IEEE TPAMI 13(4)).

    Args:
        src: Points to transform.
        dst: Target points.
        with_scale: Fit the scale s (else s = 1).
        allow_reflection: Allow det(R) = -1 (drop the sign correction S of Eq. 39).

    Shapes:
        src, dst: (n, d); returns s, R (d, d), t (d,).

    Raises:
        DatasetError: with fewer than d + 1 points or degenerate (constant) source points.
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    n, d = src.shape
    if n < d + 1 or dst.shape != src.shape:
        raise DatasetError(f'Umeyama alignment needs at least {d + 1} matching points '
                           f'(got {n} source, {len(dst)} target)')
    mu_x = src.mean(axis=0)                                  # Eq. 34
    mu_y = dst.mean(axis=0)                                  # Eq. 35
    xc = src - mu_x
    yc = dst - mu_y
    var_x = float(np.mean(np.sum(xc * xc, axis=1)))          # Eq. 36
    if var_x < 1e-18:
        raise DatasetError('the estimate does not move during the calibration segment: '
                           'cannot calibrate a constant trajectory')
    cov = yc.T @ xc / n                                      # Eq. 38: Σ_xy
    U, D, Vt = np.linalg.svd(cov)
    S = np.eye(d)
    if not allow_reflection and np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[-1, -1] = -1.0                                     # Eq. 39
    R = U @ S @ Vt                                           # Eq. 40
    s = float(np.trace(np.diag(D) @ S) / var_x) if with_scale else 1.0   # Eq. 42
    t = mu_y - s * R @ mu_x                                  # Eq. 41
    return s, R, t


# ------------------------------------------------------------------------------------------
# Lag


def _xcorr_score(est: list[F64], gt: list[F64], k: int) -> tuple[float, list[float]]:
    """Pearson correlations of est[i] with gt[i - k] for each signal pair."""
    corrs = []
    for a, b in zip(est, gt, strict=True):
        if k >= 0:
            x, y = a[k:], b[:len(b) - k]
        else:
            x, y = a[:len(a) + k], b[-k:]
        x = x - x.mean()
        y = y - y.mean()
        den = float(np.sqrt(np.dot(x, x) * np.dot(y, y)))
        corrs.append(float(np.dot(x, y) / den) if den > 0 else 0.0)
    return 0.0, corrs


def _lag_search(t_est: F64, est: list[F64], t_gt: F64, gt: list[F64], *, rate_hz: float,
                max_lag_s: float, squared: bool) -> tuple[float, list[float]]:
    t0 = max(t_est[0], t_gt[0])
    t1 = min(t_est[-1], t_gt[-1])
    if t1 - t0 < 4 * max_lag_s + 1.0 / rate_hz:
        raise DatasetError(f'the estimate and the ground truth overlap for '
                           f'{max(t1 - t0, 0):.2f} s only; the lag search needs more than '
                           f'{4 * max_lag_s:.1f} s')
    grid = np.arange(t0, t1, 1.0 / rate_hz)
    e = [np.interp(grid, t_est, s) for s in est]
    g = [np.interp(grid, t_gt, s) for s in gt]
    K = int(round(max_lag_s * rate_hz))
    scores = np.empty(2 * K + 1)
    all_corrs = []
    for i, k in enumerate(range(-K, K + 1)):
        _, corrs = _xcorr_score(e, g, k)
        all_corrs.append(corrs)
        scores[i] = sum(c * c for c in corrs) if squared else abs(sum(corrs))
    best = int(np.argmax(scores))
    frac = 0.0
    if 0 < best < 2 * K:
        y0, y1, y2 = scores[best - 1], scores[best], scores[best + 1]
        den = y0 - 2 * y1 + y2
        if den < 0:
            frac = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5))
    return (best - K + frac) / rate_hz, all_corrs[best]


def estimate_lag(t_est: F64, sig_est: F64, t_gt: F64, sig_gt: F64, *, rate_hz: float = 400.0,
                 max_lag_s: float = 0.5) -> tuple[float, float]:
    """Lag of the estimate behind the ground truth by cross-correlation (paper Methods).

    Both signals are resampled at ``rate_hz`` on their common interval; the lag maximises the
    Pearson correlation of est(t) with gt(t - lag) for |lag| <= ``max_lag_s``.

    Shapes:
        t_est, sig_est: (n,) seconds and values; t_gt, sig_gt: (m,).

    Returns:
        (lag in seconds, correlation at that lag).
    """
    lag, corrs = _lag_search(t_est, [sig_est], t_gt, [sig_gt], rate_hz=rate_hz,
                             max_lag_s=max_lag_s, squared=False)
    return lag, corrs[0]


# ------------------------------------------------------------------------------------------
# Ground truth resampling


def _interp_gt(gt_t: F64, gt_R: F64, gt_p: F64, t: F64) -> tuple[F64, F64]:
    """Ground-truth rotations (geodesic) and positions (linear) at times ``t`` (inside)."""
    i = np.clip(np.searchsorted(gt_t, t, side='right') - 1, 0, len(gt_t) - 2)
    span = gt_t[i + 1] - gt_t[i]
    a = np.clip((t - gt_t[i]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    p = gt_p[i] + a[:, None] * (gt_p[i + 1] - gt_p[i])
    delta = so3_log(np.swapaxes(gt_R[i], 1, 2) @ gt_R[i + 1])
    R = gt_R[i] @ so3_exp(delta * a[:, None])
    return R, p


def _check_inputs(gt: Trajectory, est: EstimateSeries, kind: str, calib: str,
                  convention: str) -> None:
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
    if est.z is not None and est.z.shape != (n,):
        raise DatasetError(f'estimate column z has {est.z.shape[0]} values, expected {n}')
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


def _wrap(a: F64) -> F64:
    return np.asarray((a + np.pi) % (2 * np.pi) - np.pi, dtype=np.float64)


def relative_position_errors(p_gt: F64, R_gt: F64, p_est: F64, R_est: F64,
                             lengths: tuple[float, ...]) -> dict[float, F64]:
    """rpg-style relative translation errors in % of the sub-trajectory length.

    For each length L and each start pose i, the end pose j is the one whose distance travelled
    along the ground truth is closest to d_i + L (kept if within 0.2 L); the error is
    ``|R_est,i^T (p_est,j - p_est,i) - R_gt,i^T (p_gt,j - p_gt,i)| / L * 100``.

    Shapes:
        p_gt, p_est: (n, 3); R_gt, R_est: (n, 3, 3). Returns one (m_L,) array per length.
    """
    dist = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p_gt, axis=0), axis=1))])
    out: dict[float, F64] = {}
    for L in lengths:
        if L <= 0:
            continue
        j = np.searchsorted(dist, dist + L)
        j = np.clip(j, 0, len(dist) - 1)
        jm = np.clip(j - 1, 0, len(dist) - 1)
        better = np.abs(dist[jm] - dist - L) < np.abs(dist[j] - dist - L)
        j = np.where(better, jm, j)
        ok = (np.abs(dist[j] - dist - L) <= 0.2 * L) & (j > np.arange(len(dist)))
        i = np.flatnonzero(ok)
        j = j[ok]
        d_gt = np.einsum('nji,nj->ni', R_gt[i], p_gt[j] - p_gt[i])
        d_est = np.einsum('nji,nj->ni', R_est[i], p_est[j] - p_est[i])
        out[L] = np.linalg.norm(d_est - d_gt, axis=1) / L * 100.0
    return out


def _fit_depth(z: F64, target: F64) -> tuple[float, float, float]:
    """Fit target ≈ a + b exp(k z) (k by grid search, a and b by least squares)."""
    best = (float('inf'), 0.0, float(np.mean(target)), 0.0)
    zc = z - np.median(z)
    for k in np.concatenate([np.linspace(-4, -0.05, 80), np.linspace(0.05, 4, 80)]):
        A = np.stack([np.ones_like(zc), np.exp(k * zc)], axis=1)
        coef, *_ = np.linalg.lstsq(A, target, rcond=None)
        res = float(np.sum((A @ coef - target) ** 2))
        if res < best[0]:
            best = (res, float(k), float(coef[0]), float(coef[1]))
    _, k, a, b = best
    # express with the un-centred z: b exp(k (z - m)) = (b exp(-k m)) exp(k z)
    return k, a, b * float(np.exp(-k * np.median(z)))


# ------------------------------------------------------------------------------------------
# The protocol


def evaluate(gt: Trajectory, est: EstimateSeries, kind: str, *, calib: str = 'last10',
             lag_s: float | None = None, max_lag_s: float = 0.5,
             convention: str = 'swing-twist', roll_zero_s: float = 0.1) -> EvalResult:
    """Evaluate a raw estimate against the ground truth with the paper's protocol.

    Args:
        gt: Ground-truth camera poses (camera-to-world), time-ordered.
        est: Raw readouts (h, v, r[, z]) of the network or the baseline.
        kind: ``'rotation'``, ``'translation'`` or ``'arm'``.
        calib: ``'last10'`` (last 10 s of the training part) or ``'full'`` (rotation only; the
            other kinds have fixed calibration segments, see the module docstring).
        lag_s: Use this lag instead of estimating it (seconds, + = estimate lags).
        max_lag_s: Largest lag searched.
        convention: ``'swing-twist'`` or ``'euler'`` pan/tilt/roll (module docstring).
        roll_zero_s: The roll is zeroed on the estimates of the first ``roll_zero_s`` seconds
            (0.1: the protocol; longer only as a diagnostic).

    Returns:
        The metrics, calibration, lag, counts, warnings and aligned series.

    Raises:
        DatasetError: on bad or insufficient inputs (see the module docstring).
        ConfigError: on an unknown kind or calibration mode.
    """
    _check_inputs(gt, est, kind, calib, convention)
    if not 0.0 < roll_zero_s < 1e3:
        raise ConfigError(f'roll_zero_s = {roll_zero_s}: give the roll zeroing window in seconds '
                          '(> 0; the protocol uses 0.1)')
    warnings: list[str] = []
    gt_t = gt.t.astype(np.float64) * 1e-9
    gt_R = quat_to_matrix(gt.quat)
    gt_p = np.asarray(gt.pos, dtype=np.float64)
    t_raw = est.t.astype(np.float64) * 1e-9
    to_angles, to_matrix = _CONVENTIONS[convention]
    _, _, roll_abs = to_angles(np.swapaxes(gt_R[:1], 1, 2) @ gt_R)
    roll_abs = np.unwrap(roll_abs)

    # 1. lag (paper: cross-correlation of the roll at 400 Hz)
    if kind == 'translation':
        q_all = np.einsum('ji,nj->ni', gt_R[0], gt_p - gt_p[0])
        lag_found, _ = _lag_search(t_raw, [est.h, est.h, est.v, est.v], gt_t,
                                   [q_all[:, 0], q_all[:, 1], q_all[:, 0], q_all[:, 1]],
                                   rate_hz=400.0, max_lag_s=max_lag_s, squared=True)
    else:
        lag_found, _ = _lag_search(t_raw, [est.r], gt_t, [roll_abs], rate_hz=400.0,
                                   max_lag_s=max_lag_s, squared=False)
    lag = lag_found if lag_s is None else float(lag_s)
    if lag_s is None and abs(abs(lag) - max_lag_s) < 2.5e-3:
        warnings.append(f'the lag {lag:+.3f} s is at the edge of the search range '
                        f'±{max_lag_s} s: the estimate may not follow the ground truth')
    t = t_raw - lag
    inside = (t >= gt_t[0]) & (t <= gt_t[-1])
    if int(inside.sum()) < MIN_SAMPLES:
        raise DatasetError(f'only {int(inside.sum())} estimates fall inside the ground truth '
                           f'after the lag correction ({lag:+.3f} s)')
    if not np.all(inside):
        warnings.append(f'{int((~inside).sum())} estimates outside the ground-truth time range '
                        'were dropped')
    t = t[inside]
    h, v, r = est.h[inside], est.v[inside], est.r[inside]
    z = None if est.z is None else est.z[inside]

    # roll correlation at the chosen lag (sign check)
    roll_gt_at = np.interp(t, gt_t, roll_abs)
    rc = np.corrcoef(r, roll_gt_at)[0, 1] if np.std(r) > 0 and np.std(roll_gt_at) > 0 else 0.0
    roll_corr = float(rc)
    if roll_corr < -0.3:
        warnings.append(f'the roll is anti-correlated with the ground truth (r = {roll_corr:.2f}):'
                        " the estimate's roll sign looks flipped")
    elif kind != 'translation' and roll_corr < 0.5:
        warnings.append(f'the roll correlates poorly with the ground truth (r = {roll_corr:.2f})')

    # 2. ground truth at the estimate times, relative to the pose at t0
    R_at, p_at = _interp_gt(gt_t, gt_R, gt_p, t)
    R_rel = np.swapaxes(R_at[:1], 1, 2) @ R_at
    q = np.einsum('ji,nj->ni', R_at[0], p_at - p_at[0])
    pan_gt, tilt_gt, roll_gt = to_angles(R_rel)
    roll_gt = np.unwrap(roll_gt)

    # roll zeroed at the start (median over the first 0.1 s of estimates), not calibrated
    start = t <= t[0] + roll_zero_s
    if int(start.sum()) < 3:
        start = np.arange(len(t)) < 3
    roll_offset = float(np.median(r[start] - roll_gt[start]))
    roll_est = r - roll_offset

    # 3. split by ground-truth line order
    split = float(gt_t[int(TRAIN_FRACTION * len(gt_t))])
    train = t < split
    test = ~train
    hv = np.stack([h, v], axis=1)
    cal_info: dict[str, float | bool | str] = {'roll_offset_rad': roll_offset,
                                               'roll_zero_s': roll_zero_s,
                                               'convention': convention}

    if kind == 'arm':
        t_start = float(gt_t[0])
        calib_mask = (t >= t_start + 0.5) & (t <= t_start + 5.0)
        test = t > t_start + 5.0
        if calib != 'last10':
            warnings.append('--calib is ignored for the arm: the first arc (0.5–5 s) is used')
        cal_name = 'first arc 0.5–5 s'
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
    cal_info['segment'] = cal_name

    # 4./5. per kind
    metrics: dict[str, float] = {}
    deg = 180.0 / np.pi
    if kind == 'rotation':
        target = np.stack([pan_gt, tilt_gt], axis=1)
        s, Rc, tc = umeyama(hv[calib_mask], target[calib_mask], allow_reflection=True)
        pt = (s * (Rc @ hv.T)).T + tc
        R_est = to_matrix(pt[:, 0], pt[:, 1], roll_est)
        err = rotation_angle(np.swapaxes(R_rel, 1, 2) @ R_est) * deg
        metrics['median_angle_deg'] = float(np.median(err[test]))
        metrics['mean_angle_deg'] = float(np.mean(err[test]))
        metrics['p90_angle_deg'] = float(np.percentile(err[test], 90))
        metrics['median_pan_deg'] = float(np.median(np.abs(pt[test, 0] - pan_gt[test])) * deg)
        metrics['median_tilt_deg'] = float(np.median(np.abs(pt[test, 1] - tilt_gt[test])) * deg)
        metrics['median_roll_deg'] = float(np.median(np.abs(_wrap(roll_est - roll_gt)[test]))
                                           * deg)
        gt_plot = np.stack([pan_gt, tilt_gt, roll_gt], axis=1) * deg
        est_plot = np.stack([pt[:, 0], pt[:, 1], roll_est], axis=1) * deg
        labels, units, err_label = ('pan', 'tilt', 'roll'), ('deg', 'deg', 'deg'), 'angle (deg)'
        cal_info.update(_sim_info(s, Rc, tc, 'rad per px'))
    else:
        target = q[:, :2]
        s, Rc, tc = umeyama(hv[calib_mask], target[calib_mask], allow_reflection=True)
        xy = (s * (Rc @ hv.T)).T + tc
        if kind == 'translation':
            if z is not None and np.std(z[calib_mask]) > 0:
                k, a, b = _fit_depth(z[calib_mask], q[calib_mask, 2])
                zz = a + b * np.exp(k * z)
                cal_info.update(depth_k=k, depth_a=a, depth_b=b)
            else:
                zz = np.full(len(t), float(np.mean(q[calib_mask, 2])))
                warnings.append('no scale column z: the depth is taken as constant')
            p_est = np.column_stack([xy, zz])
        else:
            p_est = np.column_stack([xy, np.zeros(len(t))])
        perr = np.linalg.norm(p_est - q, axis=1)
        rerr = np.abs(_wrap(roll_est - roll_gt)) * deg
        metrics['median_pos_m'] = float(np.median(perr[test]))
        metrics['mean_pos_m'] = float(np.mean(perr[test]))
        metrics['median_roll_deg'] = float(np.median(rerr[test]))
        if kind == 'translation':
            rel = _rpg_relative(q[test], R_rel[test], p_est[test], roll_est[test])
            metrics.update(rel)
        gt_plot = q.copy()
        est_plot = p_est.copy()
        if kind == 'arm':
            gt_plot[:, 2] = roll_gt * deg
            est_plot[:, 2] = roll_est * deg
            labels, units = ('x', 'y', 'roll'), ('m', 'm', 'deg')
        else:
            labels, units = ('x', 'y', 'z'), ('m', 'm', 'm')
        err = perr
        err_label = 'position (m)'
        cal_info.update(_sim_info(s, Rc, tc, 'm per px'))

    series = EvalSeries(t - gt_t[0], gt_plot, est_plot, err, calib_mask, test, labels, units,
                        err_label)
    counts = {'estimates': len(est), 'used': len(t), 'calibration': n_cal,
              'evaluated': int(test.sum())}
    return EvalResult(kind, calib, lag, roll_corr, metrics, cal_info, counts, split - gt_t[0],
                      tuple(warnings), series)


def lag_scan(gt: Trajectory, est: EstimateSeries, kind: str, offsets_s: F64, *,
             calib: str = 'last10', lag_s: float | None = None,
             max_lag_s: float = 0.5, convention: str = 'swing-twist',
             roll_zero_s: float = 0.1) -> tuple[float, dict[str, list[float]]]:
    """Every metric with the time alignment moved by each offset (a diagnostic, not the
    protocol): how steeply the errors depend on the lag, and which lag each metric prefers.

    The protocol aligns time by the roll; a position that lags the roll by a few ms (e.g. the
    arm, where ±4 ms move the median position error by ~30 %) shows up as a position minimum
    away from offset 0.

    Args:
        gt, est, kind, calib, max_lag_s, convention, roll_zero_s: as for :func:`evaluate`.
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
                     roll_zero_s=roll_zero_s).lag_s if lag_s is None else float(lag_s))
    curves: dict[str, list[float]] = {}
    for d in offsets:
        res = evaluate(gt, est, kind, calib=calib, lag_s=base + float(d),
                       convention=convention, roll_zero_s=roll_zero_s)
        for name, value in res.metrics.items():
            curves.setdefault(name, []).append(float(value))
    return base, curves


def _sim_info(s: float, R: F64, t: F64, unit: str) -> dict[str, float | bool | str]:
    reflected = bool(np.linalg.det(R) < 0)
    return {'scale': s, 'scale_unit': unit, 'angle_deg': float(np.degrees(
        np.arctan2(R[1, 0], R[0, 0]))), 'reflected': reflected, 'tx': float(t[0]),
        'ty': float(t[1])}


def _rpg_relative(q: F64, R_rel: F64, p_est: F64, roll_est: F64) -> dict[str, float]:
    """Relative position error (%) on the test part after sim(3) alignment (rpg style)."""
    s, Ra, ta = umeyama(p_est, q, with_scale=True, allow_reflection=False)
    p_al = (s * (Ra @ p_est.T)).T + ta
    R_est = Ra[None] @ rot_z(roll_est)
    path = float(np.sum(np.linalg.norm(np.diff(q, axis=0), axis=1)))
    lengths = tuple(float(np.floor(f * path * 100) / 100) for f in RPG_FRACTIONS)
    errs = relative_position_errors(q, R_rel, p_al, R_est, lengths)
    allv = np.concatenate([e for e in errs.values() if e.size] or [np.array([np.nan])])
    medians = [float(np.median(e)) for e in errs.values() if e.size]
    return {'rel_pos_pct': float(np.median(allv)),
            'rel_pos_pct_mean_of_medians': float(np.mean(medians)) if medians else float('nan'),
            'test_path_m': path, 'sim3_scale': s}
