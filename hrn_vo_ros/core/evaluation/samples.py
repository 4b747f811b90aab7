"""The estimate and the ground truth on common samples: rotation conventions, ground truth at
the estimate times (relative to the first estimate's pose), and the roll zeroing.

**Rotation convention.** Pan, tilt and roll (of the ground truth, and of the estimate when it
is turned back into a rotation) are **swing-twist** angles by default,
``R = exp([tilt, pan, 0]^) Rz(roll)``: the swing points the optical axis, the twist turns the
camera about it. This is what an estimator of an image shift and of an image rotation about
the image centre measures (after the equidistant rectification the shift is the swing angle
times the focal length, and the image turns by the twist at its centre).
``convention='euler'`` uses ``R = Ry(pan) Rx(tilt) Rz(roll)`` instead, whose roll carries an
extra twist of about ``-pan * tilt / 2`` that no image-plane estimator sees (0.3° at
pan = tilt = 6°). The roll used for the lag and the zeroing follows the same convention. The
geodesic error of a perfect estimate is zero in its own convention; the conventions agree to
first order.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrn_vo_ros.core.evaluation.series import EstimateSeries, F64
from hrn_vo_ros.core.events.sequence import Trajectory
from hrn_vo_ros.core.odometry.geometry import (
    euler_ptr_to_matrix,
    matrix_to_euler_ptr,
    matrix_to_swing_twist,
    quat_to_matrix,
    so3_exp,
    so3_log,
    swing_twist_to_matrix,
)

ToAngles = Callable[[F64], tuple[F64, F64, F64]]
ToMatrix = Callable[[ArrayLike, ArrayLike, ArrayLike], F64]
CONVENTIONS: dict[str, tuple[ToAngles, ToMatrix]] = {
    'swing-twist': (matrix_to_swing_twist, swing_twist_to_matrix),
    'euler': (matrix_to_euler_ptr, euler_ptr_to_matrix),
}
"""Rotation convention -> (R -> (pan, tilt, roll), (pan, tilt, roll) -> R)."""
ROTATION_CONVENTIONS = tuple(CONVENTIONS)


@dataclass(frozen=True, slots=True, eq=False)
class GroundTruthArrays:
    """The ground truth as float arrays.

    Shapes:
        t: (m,) seconds; R: (m, 3, 3) camera to world; p: (m, 3) metres; roll: (m,) unwrapped
        roll (radians) relative to the first pose, in the chosen convention.
    """

    t: F64
    R: F64
    p: F64
    roll: F64

    @classmethod
    def from_trajectory(cls, gt: Trajectory, convention: str) -> GroundTruthArrays:
        """Times in seconds, rotation matrices and the relative roll of ``gt``."""
        R = quat_to_matrix(gt.quat)
        to_angles, _ = CONVENTIONS[convention]
        _, _, roll = to_angles(np.swapaxes(R[:1], 1, 2) @ R)
        return cls(t=gt.t.astype(np.float64) * 1e-9, R=R,
                   p=np.asarray(gt.pos, dtype=np.float64), roll=np.unwrap(roll))


@dataclass(frozen=True, slots=True, eq=False)
class AlignedSamples:
    """Estimates that fall inside the ground truth after the lag correction, and the ground
    truth at their times relative to the pose at the first of them (t0).

    ``R_rel(t) = R_gt(t0)^T R_gt(t)`` and ``q(t) = R_gt(t0)^T (p_gt(t) - p_gt(t0))`` (first
    camera frame: x right, y down, z forward); pan, tilt and roll are the angles of ``R_rel``.

    Shapes:
        t, r, pan, tilt, roll, roll_est: (n,); hv: (n, 2) raw readouts; z: (n,) or None;
        R_rel: (n, 3, 3); q: (n, 3).
    """

    t: F64
    hv: F64
    r: F64
    z: F64 | None
    R_rel: F64
    q: F64
    pan: F64
    tilt: F64
    roll: F64
    roll_est: F64
    roll_offset: float
    convention: str


def interp_gt(gt_t: F64, gt_R: F64, gt_p: F64, t: F64) -> tuple[F64, F64]:
    """Ground-truth rotations (geodesic) and positions (linear) at times ``t`` (inside).

    Shapes:
        gt_t: (m,); gt_R: (m, 3, 3); gt_p: (m, 3); t: (n,) -> (n, 3, 3), (n, 3).
    """
    i = np.clip(np.searchsorted(gt_t, t, side='right') - 1, 0, len(gt_t) - 2)
    span = gt_t[i + 1] - gt_t[i]
    a = np.clip((t - gt_t[i]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    p = gt_p[i] + a[:, None] * (gt_p[i + 1] - gt_p[i])
    delta = so3_log(np.swapaxes(gt_R[i], 1, 2) @ gt_R[i + 1])
    R = gt_R[i] @ so3_exp(delta * a[:, None])
    return R, p


def motion_between(gt: Trajectory, t_ns: NDArray[np.int64], q: float = 95.0
                   ) -> tuple[float, float]:
    """The camera's motion from each of the times ``t_ns`` to the next (between event frames:
    the motion one frame spans): the ``q``-th percentile of the turn (degrees, the geodesic
    angle between the orientations) and of the travel (metres), the ground truth interpolated
    as :func:`interp_gt` (times outside it count as its first or last pose). NaN for fewer
    than two times.

    Shapes:
        t_ns: (n,) int64 ns, non-decreasing.
    """
    if len(t_ns) < 2:
        return float('nan'), float('nan')
    R, p = interp_gt(gt.t.astype(np.float64) * 1e-9, quat_to_matrix(gt.quat),
                     np.asarray(gt.pos, dtype=np.float64),
                     np.asarray(t_ns, dtype=np.int64).astype(np.float64) * 1e-9)
    turn = np.degrees(np.linalg.norm(so3_log(np.swapaxes(R[:-1], 1, 2) @ R[1:]), axis=1))
    travel = np.linalg.norm(np.diff(p, axis=0), axis=1)
    return float(np.percentile(turn, q)), float(np.percentile(travel, q))


def roll_correlation(t: F64, r: F64, gt: GroundTruthArrays) -> float:
    """Pearson correlation of the raw roll with the ground-truth roll (0 if either is flat)."""
    roll_gt_at = np.interp(t, gt.t, gt.roll)
    rc = np.corrcoef(r, roll_gt_at)[0, 1] if np.std(r) > 0 and np.std(roll_gt_at) > 0 else 0.0
    return float(rc)


def align_samples(gt: GroundTruthArrays, t: F64, est: EstimateSeries, inside: NDArray[np.bool_],
                  *, convention: str, roll_zero_s: float) -> AlignedSamples:
    """The estimates selected by ``inside`` at the lag-corrected times ``t`` (seconds, already
    selected), with the relative ground truth and the zeroed roll.

    The roll is not calibrated, only zeroed: ``roll_est = r - offset`` with
    ``offset = median(r - roll_gt)`` over the estimates of the first ``roll_zero_s`` seconds
    (at least the first three).
    """
    hv = np.stack([est.h[inside], est.v[inside]], axis=1)
    r = est.r[inside]
    z = None if est.z is None else est.z[inside]
    R_at, p_at = interp_gt(gt.t, gt.R, gt.p, t)
    R_rel = np.swapaxes(R_at[:1], 1, 2) @ R_at
    q = np.einsum('ji,nj->ni', R_at[0], p_at - p_at[0])
    to_angles, _ = CONVENTIONS[convention]
    pan, tilt, roll = to_angles(R_rel)
    roll = np.unwrap(roll)
    start = t <= t[0] + roll_zero_s
    if int(start.sum()) < 3:
        start = np.arange(len(t)) < 3
    roll_offset = float(np.median(r[start] - roll[start]))
    return AlignedSamples(t=t, hv=hv, r=r, z=z, R_rel=R_rel, q=q, pan=pan, tilt=tilt,
                          roll=roll, roll_est=r - roll_offset, roll_offset=roll_offset,
                          convention=convention)
