"""Small rotation helpers shared by the simulator, the evaluation and the baseline.

Conventions (used everywhere in the package):

* Camera frame: x right, y down, z forward (optical axis), as in the Event Camera Dataset.
* Quaternions are (x, y, z, w), unit, Hamilton convention; ``R`` is camera-to-world.
* Euler angles **pan, tilt, roll** of a camera-to-world rotation ``R`` relative to a reference
  pose mean ``R = Ry(pan) @ Rx(tilt) @ Rz(roll)`` (intrinsic y-x'-z'': pan about the camera's
  vertical axis, then tilt about the new horizontal axis, then roll about the optical axis).
  Positive pan turns the optical axis towards +x (right), positive tilt towards -y (up),
  positive roll turns the camera clockwise about its optical axis as seen from behind.
* **Swing-twist** pan, tilt, roll mean ``R = exp([tilt, pan, 0]^) @ Rz(roll)``: a twist (roll)
  about the optical axis, then the swing, the shortest rotation that points the optical axis
  to its new direction (about an axis in the image plane). For small angles both conventions
  agree; they differ by a twist of about ``pan * tilt / 2`` (``Ry(pan) Rx(tilt)`` carries it,
  the swing does not). An estimator that reads an image shift (h, v) and an image rotation
  about the image centre measures the swing and the twist (an equidistant image shifts by
  ``f * angle`` along the swing, and turns by the twist at its centre), which is why the
  evaluation uses this convention by default (:mod:`hrn_vo_ros.core.evaluation.protocol`).

Public API: :func:`rot_x`, :func:`rot_y`, :func:`rot_z`, :func:`euler_ptr_to_matrix`,
:func:`matrix_to_euler_ptr`, :func:`swing_twist_to_matrix`, :func:`matrix_to_swing_twist`,
:func:`quat_to_matrix`, :func:`matrix_to_quat`, :func:`rotation_angle`, :func:`so3_log`,
:func:`so3_exp`; for one pose per call (the network's per-frame steps), in plain floats:
:func:`compose_swing_twist` and :func:`turn_swing_twist`.
"""

from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

F64 = NDArray[np.float64]


def _axis_rot(angle: ArrayLike, axis: int) -> F64:
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def rot_x(angle: ArrayLike) -> F64:
    """Rotation matrices about x by ``angle`` radians. Shapes: angle (...,) -> (..., 3, 3)."""
    return _axis_rot(angle, 0)


def rot_y(angle: ArrayLike) -> F64:
    """Rotation matrices about y by ``angle`` radians. Shapes: angle (...,) -> (..., 3, 3)."""
    return _axis_rot(angle, 1)


def rot_z(angle: ArrayLike) -> F64:
    """Rotation matrices about z by ``angle`` radians. Shapes: angle (...,) -> (..., 3, 3)."""
    return _axis_rot(angle, 2)


def euler_ptr_to_matrix(pan: ArrayLike, tilt: ArrayLike, roll: ArrayLike) -> F64:
    """``Ry(pan) @ Rx(tilt) @ Rz(roll)`` (see the module docstring).

    Shapes:
        pan, tilt, roll: (...,) radians, broadcastable; returns (..., 3, 3).
    """
    return rot_y(pan) @ rot_x(tilt) @ rot_z(roll)


def matrix_to_euler_ptr(R: F64) -> tuple[F64, F64, F64]:
    """Inverse of :func:`euler_ptr_to_matrix` (tilt in [-90°, 90°]; no unwrapping).

    Shapes:
        R: (..., 3, 3); returns three (...,) arrays in radians.
    """
    # Ry(a) Rx(b) Rz(c): R[1,2] = -sin b, R[0,2] = sin a cos b, R[2,2] = cos a cos b,
    # R[1,0] = cos b sin c, R[1,1] = cos b cos c.
    tilt = np.arcsin(np.clip(-R[..., 1, 2], -1.0, 1.0))
    pan = np.arctan2(R[..., 0, 2], R[..., 2, 2])
    roll = np.arctan2(R[..., 1, 0], R[..., 1, 1])
    return pan, tilt, roll


def swing_twist_to_matrix(pan: ArrayLike, tilt: ArrayLike, roll: ArrayLike) -> F64:
    """``exp([tilt, pan, 0]^) @ Rz(roll)``: the swing (pan, tilt) after the twist (roll).

    Shapes:
        pan, tilt, roll: (...,) radians, broadcastable; returns (..., 3, 3).
    """
    p, t, r = np.broadcast_arrays(np.asarray(pan, dtype=np.float64),
                                  np.asarray(tilt, dtype=np.float64),
                                  np.asarray(roll, dtype=np.float64))
    swing = so3_exp(np.stack([t, p, np.zeros_like(p)], axis=-1))
    return swing @ rot_z(r)


def matrix_to_swing_twist(R: F64) -> tuple[F64, F64, F64]:
    """Inverse of :func:`swing_twist_to_matrix` (swing angle < 180°; no unwrapping).

    The swing turns the optical axis ``e_z`` to ``d = R e_z`` about ``e_z x d``; the twist is what
    is left, ``Rz(roll) = swing^T R``.

    Shapes:
        R: (..., 3, 3); returns three (...,) arrays in radians.
    """
    Ra = np.asarray(R, dtype=np.float64)
    d = Ra[..., :, 2]
    angle = np.arccos(np.clip(d[..., 2], -1.0, 1.0))
    sin_angle = np.hypot(d[..., 0], d[..., 1])
    safe = sin_angle > 1e-12
    k = np.where(safe, angle / np.where(safe, sin_angle, 1.0), 1.0)
    pan, tilt = d[..., 0] * k, -d[..., 1] * k
    twist = np.swapaxes(swing_twist_to_matrix(pan, tilt, np.zeros_like(pan)), -1, -2) @ Ra
    roll = np.arctan2(twist[..., 1, 0], twist[..., 0, 0])
    return pan, tilt, roll


def quat_to_matrix(q: ArrayLike) -> F64:
    """Rotation matrices of quaternions (x, y, z, w); normalises them first.

    Shapes:
        q: (..., 4); returns (..., 3, 3).
    """
    qa = np.asarray(q, dtype=np.float64)
    qa = qa / np.linalg.norm(qa, axis=-1, keepdims=True)
    x, y, z, w = qa[..., 0], qa[..., 1], qa[..., 2], qa[..., 3]
    out = np.empty(qa.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - z * w)
    out[..., 0, 2] = 2 * (x * z + y * w)
    out[..., 1, 0] = 2 * (x * y + z * w)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - x * w)
    out[..., 2, 0] = 2 * (x * z - y * w)
    out[..., 2, 1] = 2 * (y * z + x * w)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def matrix_to_quat(R: F64) -> F64:
    """Quaternions (x, y, z, w) with w >= 0 of rotation matrices (Shepperd's method).

    Shapes:
        R: (..., 3, 3); returns (..., 4).
    """
    m = np.asarray(R, dtype=np.float64)
    flat = m.reshape(-1, 3, 3)
    n = flat.shape[0]
    q = np.empty((n, 4))
    tr = flat[:, 0, 0] + flat[:, 1, 1] + flat[:, 2, 2]
    diag = np.stack([flat[:, 0, 0], flat[:, 1, 1], flat[:, 2, 2]], axis=1)
    case = np.where(tr > diag.max(axis=1), 3, diag.argmax(axis=1))
    for k in range(4):
        sel = case == k
        if not np.any(sel):
            continue
        a = flat[sel]
        if k == 3:
            s = 2.0 * np.sqrt(1.0 + a[:, 0, 0] + a[:, 1, 1] + a[:, 2, 2])
            q[sel] = np.stack([(a[:, 2, 1] - a[:, 1, 2]) / s, (a[:, 0, 2] - a[:, 2, 0]) / s,
                               (a[:, 1, 0] - a[:, 0, 1]) / s, 0.25 * s], axis=1)
        else:
            i, j, c = k, (k + 1) % 3, (k + 2) % 3
            s = 2.0 * np.sqrt(np.maximum(1.0 + a[:, i, i] - a[:, j, j] - a[:, c, c], 1e-300))
            qq = np.empty((a.shape[0], 4))
            qq[:, i] = 0.25 * s
            qq[:, j] = (a[:, j, i] + a[:, i, j]) / s
            qq[:, c] = (a[:, c, i] + a[:, i, c]) / s
            qq[:, 3] = (a[:, c, j] - a[:, j, c]) / s
            q[sel] = qq
    q *= np.where(q[:, 3:4] < 0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(m.shape[:-2] + (4,))


def so3_log(R: F64) -> F64:
    """Rotation vectors (axis times angle, radians) of rotation matrices.

    Shapes:
        R: (..., 3, 3); returns (..., 3).
    """
    q = matrix_to_quat(R)
    v = q[..., :3]
    sin_half = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(sin_half, q[..., 3])
    scale = np.where(sin_half > 1e-12, angle / np.maximum(sin_half, 1e-300), 2.0)
    return np.asarray(v * scale[..., None], dtype=np.float64)


def so3_exp(w: ArrayLike) -> F64:
    """Rotation matrices of rotation vectors (Rodrigues).

    Shapes:
        w: (..., 3) radians; returns (..., 3, 3).
    """
    wa = np.asarray(w, dtype=np.float64)
    theta = np.linalg.norm(wa, axis=-1)
    half = 0.5 * theta
    sinc = np.where(theta > 1e-12, np.sin(half) / np.maximum(theta, 1e-300), 0.5)
    q = np.concatenate([wa * sinc[..., None], np.cos(half)[..., None]], axis=-1)
    return quat_to_matrix(q)


def rotation_angle(R: F64) -> F64:
    """Geodesic angle (radians, in [0, pi]) of rotation matrices: ``|so3_log(R)|``.

    Shapes:
        R: (..., 3, 3); returns (...,).
    """
    return np.asarray(np.linalg.norm(so3_log(R), axis=-1), dtype=np.float64)


# -- one pose at a time, in floats (about 30x faster than the array forms above for one pose) --

Quat = tuple[float, float, float, float]
Angles = tuple[float, float, float]


def compose_swing_twist(a: Angles, b: Angles) -> Angles:
    """The swing-twist (pan, tilt, roll) of ``swing_twist_to_matrix(*a) @
    swing_twist_to_matrix(*b)`` (roll in [-pi, pi]; swing angle < 180°)."""
    return _quat_swing_twist(_quat_product(_swing_twist_quat(*a), _swing_twist_quat(*b)))


def turn_swing_twist(a: Angles, theta: Sequence[float] | F64) -> Angles:
    """The swing-twist (pan, tilt, roll) of ``swing_twist_to_matrix(*a) @ so3_exp(theta)``
    (``theta`` a rotation vector, rad; roll in [-pi, pi]; swing angle < 180°)."""
    return _quat_swing_twist(_quat_product(_swing_twist_quat(*a), _rotvec_quat(
        float(theta[0]), float(theta[1]), float(theta[2]))))


def _rotvec_quat(x: float, y: float, z: float) -> Quat:
    angle = math.sqrt(x * x + y * y + z * z)
    if angle < 1e-12:
        return (0.5 * x, 0.5 * y, 0.5 * z, 1.0)          # first order
    k = math.sin(0.5 * angle) / angle
    return (k * x, k * y, k * z, math.cos(0.5 * angle))


def _swing_twist_quat(pan: float, tilt: float, roll: float) -> Quat:
    # exp([tilt, pan, 0]^) (x) Rz(roll), quaternions (x, y, z, w)
    sx, sy, _, sw = _rotvec_quat(tilt, pan, 0.0)
    tz, tw = math.sin(0.5 * roll), math.cos(0.5 * roll)
    return (tw * sx + tz * sy, tw * sy - tz * sx, sw * tz, sw * tw)


def _quat_product(p: Quat, q: Quat) -> Quat:
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return (pw * qx + qw * px + py * qz - pz * qy, pw * qy + qw * py + pz * qx - px * qz,
            pw * qz + qw * pz + px * qy - py * qx, pw * qw - px * qx - py * qy - pz * qz)


def _quat_swing_twist(q: Quat) -> Angles:
    # q = swing (x) twist, the twist about z: q_z / q_w = tan(roll / 2), then swing = q (x)
    # twist^-1, a rotation about an axis in the image plane
    x, y, z, w = q if q[3] >= 0.0 else (-q[0], -q[1], -q[2], -q[3])
    roll = 2.0 * math.atan2(z, w)
    tz, tw = math.sin(0.5 * roll), math.cos(0.5 * roll)
    sx, sy, sw = tw * x - tz * y, tw * y + tz * x, tw * w + tz * z
    n = math.hypot(sx, sy)
    if n < 1e-15:
        return 0.0, 0.0, roll
    angle = 2.0 * math.atan2(n, sw)
    return angle * sy / n, angle * sx / n, roll
