"""The error metrics, one function per evaluation kind, on aligned samples.

Each kind function takes the :class:`~hrn_vo_ros.core.evaluation.samples.AlignedSamples`, the
calibration mask and the mask of the evaluated samples, fits the fixed calibration (Umeyama
similarity of the raw (h, v) to the target, reflections allowed because the sign convention of
the network's image axes is arbitrary) and returns a
:class:`~hrn_vo_ros.core.evaluation.series.KindResult`:

* :func:`rotation_metrics`: target (pan, tilt) of ``R_rel``; error = geodesic angle between
  ``R_rel`` and the rotation built from the calibrated pan/tilt and the zeroed roll; median,
  mean and 90th percentile in degrees, and the median absolute pan, tilt and roll errors;
* :func:`translation_metrics`: target (x, y) of ``q``, plus the depth model
  ``q_z ≈ a + b exp(k z)`` (:func:`fit_depth`; the scale state z is a log magnification,
  depth ∝ exp(-z)); error ``|p_est - q|`` (m), and the relative position error in % of the
  distance travelled (:func:`relative_position_errors` after a sim(3) alignment);
* :func:`arm_metrics`: target (x, y) of ``q``, ``p_est = (x, y, 0)`` (the estimate has no
  height); error ``|p_est - q|`` (m) and the absolute roll error (degrees).

:data:`KIND_METRICS` maps each kind to its function.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.evaluation.alignment import apply_similarity, similarity_info, umeyama
from hrn_vo_ros.core.evaluation.samples import AlignedSamples, CONVENTIONS
from hrn_vo_ros.core.evaluation.series import DEG, F64, KindResult
from hrn_vo_ros.core.odometry.geometry import rot_z, rotation_angle

Mask = NDArray[np.bool_]
RPG_FRACTIONS = (0.1, 0.2, 0.3, 0.4, 0.5)
"""Sub-trajectory lengths of the relative position error, as fractions of the test path."""


def wrap_angle(a: F64) -> F64:
    """Angles wrapped to [-π, π)."""
    return np.asarray((a + np.pi) % (2 * np.pi) - np.pi, dtype=np.float64)


def rotation_metrics(s: AlignedSamples, calib: Mask, test: Mask) -> KindResult:
    """Rotation: calibrated pan/tilt and zeroed roll against ``R_rel`` (module docstring)."""
    _, to_matrix = CONVENTIONS[s.convention]
    target = np.stack([s.pan, s.tilt], axis=1)
    sc, Rc, tc = umeyama(s.hv[calib], target[calib], allow_reflection=True)
    pt = apply_similarity(sc, Rc, tc, s.hv)
    R_est = to_matrix(pt[:, 0], pt[:, 1], s.roll_est)
    err = rotation_angle(np.swapaxes(s.R_rel, 1, 2) @ R_est) * DEG
    metrics = {
        'median_angle_deg': float(np.median(err[test])),
        'mean_angle_deg': float(np.mean(err[test])),
        'p90_angle_deg': float(np.percentile(err[test], 90)),
        'median_pan_deg': float(np.median(np.abs(pt[test, 0] - s.pan[test])) * DEG),
        'median_tilt_deg': float(np.median(np.abs(pt[test, 1] - s.tilt[test])) * DEG),
        'median_roll_deg': float(np.median(np.abs(wrap_angle(s.roll_est - s.roll)[test]))
                                 * DEG),
    }
    return KindResult(metrics=metrics, calibration=similarity_info(sc, Rc, tc, 'rad per px'),
                      gt_plot=np.stack([s.pan, s.tilt, s.roll], axis=1) * DEG,
                      est_plot=np.stack([pt[:, 0], pt[:, 1], s.roll_est], axis=1) * DEG,
                      err=err, labels=('pan', 'tilt', 'roll'), units=('deg', 'deg', 'deg'),
                      err_label='angle (deg)')


def translation_metrics(s: AlignedSamples, calib: Mask, test: Mask) -> KindResult:
    """Translation: calibrated (x, y), depth from the scale state, position and relative
    position errors (module docstring)."""
    sc, Rc, tc, xy = _calibrated_xy(s, calib)
    calibration: dict[str, float | bool | str] = {}
    warnings: tuple[str, ...] = ()
    if s.z is not None and np.std(s.z[calib]) > 0:
        k, a, b = fit_depth(s.z[calib], s.q[calib, 2])
        zz = a + b * np.exp(k * s.z)
        calibration.update(depth_k=k, depth_a=a, depth_b=b)
    else:
        zz = np.full(len(s.t), float(np.mean(s.q[calib, 2])))
        warnings = ('no scale column z: the depth is taken as constant',)
    p_est = np.column_stack([xy, zz])
    metrics, perr = _position_metrics(s, test, p_est)
    metrics.update(_rpg_relative(s.q[test], s.R_rel[test], p_est[test], s.roll_est[test]))
    calibration.update(similarity_info(sc, Rc, tc, 'm per px'))
    return KindResult(metrics=metrics, calibration=calibration, gt_plot=s.q.copy(),
                      est_plot=p_est.copy(), err=perr, labels=('x', 'y', 'z'),
                      units=('m', 'm', 'm'), err_label='position (m)', warnings=warnings)


def arm_metrics(s: AlignedSamples, calib: Mask, test: Mask) -> KindResult:
    """Robot arm: calibrated (x, y) at height 0 and the zeroed roll (module docstring)."""
    sc, Rc, tc, xy = _calibrated_xy(s, calib)
    p_est = np.column_stack([xy, np.zeros(len(s.t))])
    metrics, perr = _position_metrics(s, test, p_est)
    gt_plot = s.q.copy()
    est_plot = p_est.copy()
    gt_plot[:, 2] = s.roll * DEG
    est_plot[:, 2] = s.roll_est * DEG
    return KindResult(metrics=metrics, calibration=similarity_info(sc, Rc, tc, 'm per px'),
                      gt_plot=gt_plot, est_plot=est_plot, err=perr, labels=('x', 'y', 'roll'),
                      units=('m', 'm', 'deg'), err_label='position (m)')


KIND_METRICS: dict[str, Callable[[AlignedSamples, Mask, Mask], KindResult]] = {
    'rotation': rotation_metrics,
    'translation': translation_metrics,
    'arm': arm_metrics,
}


def _calibrated_xy(s: AlignedSamples, calib: Mask) -> tuple[float, F64, F64, F64]:
    """The similarity of (h, v) to the ground-truth (x, y) of ``q`` and the calibrated (x, y)."""
    target = s.q[:, :2]
    sc, Rc, tc = umeyama(s.hv[calib], target[calib], allow_reflection=True)
    return sc, Rc, tc, apply_similarity(sc, Rc, tc, s.hv)


def _position_metrics(s: AlignedSamples, test: Mask, p_est: F64) -> tuple[dict[str, float], F64]:
    """Median and mean position error (m) and median roll error (deg) on the test samples,
    and the per-sample position error."""
    perr = np.linalg.norm(p_est - s.q, axis=1)
    rerr = np.abs(wrap_angle(s.roll_est - s.roll)) * DEG
    metrics = {'median_pos_m': float(np.median(perr[test])),
               'mean_pos_m': float(np.mean(perr[test])),
               'median_roll_deg': float(np.median(rerr[test]))}
    return metrics, perr


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


def fit_depth(z: F64, target: F64) -> tuple[float, float, float]:
    """Fit ``target ≈ a + b exp(k z)`` (k by grid search, a and b by least squares).

    Shapes:
        z, target: (n,). Returns (k, a, b).
    """
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


def _rpg_relative(q: F64, R_rel: F64, p_est: F64, roll_est: F64) -> dict[str, float]:
    """Relative position error (%) on the test part after sim(3) alignment (rpg style).

    The test part is aligned with sim(3) (Umeyama, all poses); sub-trajectories of 10-50 % of
    the test path length start at every pose; the estimated orientation is ``Rz(roll)`` (pan
    and tilt are not estimated). Reported: the median over all sub-trajectories and lengths
    (``rel_pos_pct``) and the mean of the per-length medians.
    """
    s, Ra, ta = umeyama(p_est, q, with_scale=True, allow_reflection=False)
    p_al = apply_similarity(s, Ra, ta, p_est)
    R_est = Ra[None] @ rot_z(roll_est)
    path = float(np.sum(np.linalg.norm(np.diff(q, axis=0), axis=1)))
    lengths = tuple(float(np.floor(f * path * 100) / 100) for f in RPG_FRACTIONS)
    errs = relative_position_errors(q, R_rel, p_al, R_est, lengths)
    allv = np.concatenate([e for e in errs.values() if e.size] or [np.array([np.nan])])
    medians = [float(np.median(e)) for e in errs.values() if e.size]
    return {'rel_pos_pct': float(np.median(allv)),
            'rel_pos_pct_mean_of_medians': float(np.mean(medians)) if medians else float('nan'),
            'test_path_m': path, 'sim3_scale': s}
