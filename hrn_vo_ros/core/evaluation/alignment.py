"""Least-squares similarity alignment of point sets (Umeyama 1991, IEEE TPAMI 13(4), 376-380).

The calibration of the raw (h, v) readouts and the sim(3) alignment of the relative position
error both use :func:`umeyama`; the equation numbers on the lines are those of the paper.
"""

from __future__ import annotations

import numpy as np

from hrn_vo_ros.core.evaluation.series import F64
from hrn_vo_ros.errors import DatasetError


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
    mu_x = src.mean(axis=0)                                  # Eq. 34: mean of the source
    mu_y = dst.mean(axis=0)                                  # Eq. 35: mean of the target
    xc = src - mu_x
    yc = dst - mu_y
    var_x = float(np.mean(np.sum(xc * xc, axis=1)))          # Eq. 36: σ_x², source variance
    if var_x < 1e-18:
        raise DatasetError('the estimate does not move during the calibration segment: '
                           'cannot calibrate a constant trajectory')
    cov = yc.T @ xc / n                                      # Eq. 38: Σ_xy, cross-covariance
    U, D, Vt = np.linalg.svd(cov)                            # Σ_xy = U D V^T
    S = np.eye(d)
    if not allow_reflection and np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[-1, -1] = -1.0                                     # Eq. 39: S = diag(1, .., 1, -1)
    R = U @ S @ Vt                                           # Eq. 40: R = U S V^T
    s = float(np.trace(np.diag(D) @ S) / var_x) if with_scale else 1.0   # Eq. 42: tr(DS)/σ_x²
    t = mu_y - s * R @ mu_x                                  # Eq. 41: t = μ_y - s R μ_x
    return s, R, t


def apply_similarity(s: float, R: F64, t: F64, points: F64) -> F64:
    """``s R p + t`` for every row p of ``points`` (the transform :func:`umeyama` fits).

    Shapes:
        points: (n, d); R: (d, d); t: (d,); returns (n, d).
    """
    return np.asarray((s * (R @ points.T)).T + t, dtype=np.float64)


def similarity_info(s: float, R: F64, t: F64, unit: str) -> dict[str, float | bool | str]:
    """A fitted 2-D similarity as report entries: scale, rotation angle, reflection, shift."""
    reflected = bool(np.linalg.det(R) < 0)
    return {'scale': s, 'scale_unit': unit, 'angle_deg': float(np.degrees(
        np.arctan2(R[1, 0], R[0, 0]))), 'reflected': reflected, 'tx': float(t[0]),
        'ty': float(t[1])}
