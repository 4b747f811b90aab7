"""Time lag of an estimate behind the ground truth, by cross-correlation.

Both signals are resampled to a fixed grid (400 Hz in the protocol) by linear interpolation on
their common interval; each lag within ±``max_lag_s`` gets the Pearson correlation of est(t)
with gt(t - lag), and the best lag is refined to a fraction of a grid step by a parabola
through the scores around the maximum. ``lag > 0`` means the estimate lags.

:func:`estimate_lag` correlates one signal pair; :func:`protocol_lag` is the protocol's choice
of signals per kind (the roll, or (h, v) against the ground-truth x and y for translation).
"""

from __future__ import annotations

import numpy as np

from hrn_vo_ros.core.evaluation.series import EstimateSeries, F64
from hrn_vo_ros.errors import DatasetError

PROTOCOL_RATE_HZ = 400.0


def _xcorr_score(est: list[F64], gt: list[F64], k: int) -> list[float]:
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
    return corrs


def lag_search(t_est: F64, est: list[F64], t_gt: F64, gt: list[F64], *, rate_hz: float,
               max_lag_s: float, squared: bool) -> tuple[float, list[float]]:
    """The lag that best aligns several signal pairs at once.

    The score of a lag is the sum of the squared correlations of the pairs (``squared``) or the
    absolute value of their sum.

    Shapes:
        t_est: (n,) seconds with one (n,) signal per entry of ``est``; t_gt: (m,) likewise.

    Returns:
        (lag in seconds, the correlation of each pair at the grid lag chosen).

    Raises:
        DatasetError: when the signals overlap for less than 4 ``max_lag_s``.
    """
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
        corrs = _xcorr_score(e, g, k)
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


def estimate_lag(t_est: F64, sig_est: F64, t_gt: F64, sig_gt: F64, *,
                 rate_hz: float = PROTOCOL_RATE_HZ, max_lag_s: float = 0.5,
                 ) -> tuple[float, float]:
    """Lag of the estimate behind the ground truth by cross-correlation (paper Methods).

    Both signals are resampled at ``rate_hz`` on their common interval; the lag maximises the
    Pearson correlation of est(t) with gt(t - lag) for |lag| <= ``max_lag_s``.

    Shapes:
        t_est, sig_est: (n,) seconds and values; t_gt, sig_gt: (m,).

    Returns:
        (lag in seconds, correlation at that lag).
    """
    lag, corrs = lag_search(t_est, [sig_est], t_gt, [sig_gt], rate_hz=rate_hz,
                            max_lag_s=max_lag_s, squared=False)
    return lag, corrs[0]


def protocol_lag(kind: str, t_est: F64, est: EstimateSeries, gt_t: F64, gt_R: F64, gt_p: F64,
                 roll_gt: F64, *, max_lag_s: float) -> float:
    """The protocol's lag: the roll for rotation and arm; for translation (little roll) the
    sum of squared correlations of h and v with each of the ground-truth x and y.

    Args:
        kind: The evaluation kind.
        t_est: Estimate times, seconds.
        est: The raw readouts.
        gt_t: Ground-truth times, seconds.
        gt_R: Ground-truth rotations (camera to world).
        gt_p: Ground-truth positions.
        roll_gt: Unwrapped ground-truth roll relative to the first pose.
        max_lag_s: Largest lag searched.

    Shapes:
        t_est: (n,); gt_t, roll_gt: (m,); gt_R: (m, 3, 3); gt_p: (m, 3).
    """
    if kind == 'translation':
        q_all = np.einsum('ji,nj->ni', gt_R[0], gt_p - gt_p[0])
        lag, _ = lag_search(t_est, [est.h, est.h, est.v, est.v], gt_t,
                            [q_all[:, 0], q_all[:, 1], q_all[:, 0], q_all[:, 1]],
                            rate_hz=PROTOCOL_RATE_HZ, max_lag_s=max_lag_s, squared=True)
    else:
        lag, _ = lag_search(t_est, [est.r], gt_t, [roll_gt], rate_hz=PROTOCOL_RATE_HZ,
                            max_lag_s=max_lag_s, squared=False)
    return lag
