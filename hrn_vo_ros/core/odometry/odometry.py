"""From HRN readouts (h, v, r [, z]) to a metric/angular pose with covariance (REP-103/105).

The resonator reads out, per event frame (its factors: the view against the map):

* ``h``, ``v``: the camera position in the map, in downsampled pixels (x right, y down);
* ``r``: the roll about the optical axis in radians (right-handed about the optical z axis);
* ``z``: the log scale (log of the image magnification; positive = closer to the scene).

Calibration (parameters of :class:`OdometryConfig`, documented per field):

* ``motion_model = 'rotation'`` (a camera turning about its centre, shapes_rotation-like): the
  pixel offsets are angles through the focal length ``f`` in downsampled pixels:
  pan ``β = atan(scale·h/f)`` about the optical y axis (positive looks right), tilt
  ``α = -atan(scale·v/f)`` about the optical x axis (positive looks up), roll ``r`` about the
  optical z axis; orientation ``R = R_y(β) R_x(α) R_z(r)``, position 0.
* ``motion_model = 'translation'`` (a camera moving parallel to a plane at depth ``d``):
  ``x = scale·h·d/f``, ``y = scale·v·d/f`` (metres, optical frame), ``z = d·(1 - exp(-z))``
  (moving towards the plane magnifies it), orientation ``R_z(r)``.

Frames: the pose is the camera's motion relative to its first frame. With ``child_frame =
'camera'`` it is reported in the optical convention (x right, y down, z forward; parent = the
initial optical frame). With ``child_frame = 'base_link'`` (default, REP-103: x forward, y left,
z up) the camera is assumed mounted looking along base_link's x axis with its optical centre at
the base_link origin, so ``T_odom_base = B T_cam0_cam B^T`` with ``B = R_base_optical``
(optical z → base x, optical x → base −y, optical y → base −z).

Covariance: the readout confidence ``c`` of each factor (0..1, 1 = a sharp, unambiguous peak)
scales a per-factor standard deviation at full confidence, ``σ = σ_full / max(c, c_min)``,
propagated to metres/radians by the calibration above; axes the motion model does not observe
get ``unobserved_variance``. The matrix is the row-major 6×6 over (x, y, z, rot X, rot Y, rot Z)
of ``geometry_msgs/PoseWithCovariance`` in the parent frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.configbase import param, validate

# Rotation from the camera optical frame to base_link (REP-103): columns are the optical axes
# expressed in base_link coordinates.
R_BASE_OPTICAL = np.array([[0.0, 0.0, 1.0],
                           [-1.0, 0.0, 0.0],
                           [0.0, -1.0, 0.0]])


@dataclass(frozen=True, slots=True)
class OdometryConfig:
    """Calibration from readout units to metres/radians, frames, and the covariance model."""

    motion_model: str = param('rotation', 'How h, v become a pose: rotation (pan/tilt angles '
                              'through the focal length) or translation (metres at a depth)',
                              choices=('rotation', 'translation'))
    focal_length_px: float = param(79.6, 'Focal length in downsampled pixels (fx of calib.txt '
                                   'divided by the downsampling factor; DAVIS240C: 199/2.5)',
                                   lo=1e-3, hi=1e6)
    depth_m: float = param(1.0, 'Distance from the camera to the scene plane in metres '
                           '(translation model only)', lo=1e-6, hi=1e6)
    scale: float = param(1.0, 'Extra factor on h and v, e.g. a scale fitted by Umeyama '
                         'calibration (dimensionless)', lo=1e-9, hi=1e9)
    child_frame: str = param('base_link', 'Which body the pose describes: base_link (REP-103, '
                             'camera looking along x) or camera (optical frame: z forward)',
                             choices=('base_link', 'camera'))
    sigma_px: float = param(0.5, 'Standard deviation of h and v at full confidence, in '
                            'downsampled pixels', lo=0.0, hi=1e6)
    sigma_roll_rad: float = param(0.01, 'Standard deviation of the roll at full confidence, '
                                  'radians', lo=0.0, hi=10.0)
    sigma_log_scale: float = param(0.01, 'Standard deviation of the log scale z at full '
                                   'confidence', lo=0.0, hi=10.0)
    min_confidence: float = param(0.05, 'Confidence floor: a factor at or below it gets '
                                  'sigma/min_confidence', lo=1e-6, hi=1.0)
    unobserved_variance: float = param(1e4, 'Variance of the axes the motion model does not '
                                       'observe (rtabmap-style large value)', lo=0.0, hi=1e12)

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, slots=True, eq=False)
class OdomPose:
    """A pose of the child frame in the odometry frame at sensor time ``t_ns``.

    Shapes:
        position: (3,) metres; quat: (4,) x, y, z, w; covariance: (6, 6) over
        (x, y, z, rot X, rot Y, rot Z).
    """

    t_ns: int
    position: NDArray[np.float64]
    quat: NDArray[np.float64]
    covariance: NDArray[np.float64]


def rot_x(a: float) -> NDArray[np.float64]:
    """Rotation matrix about x by ``a`` radians (right-handed)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> NDArray[np.float64]:
    """Rotation matrix about y by ``a`` radians (right-handed)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> NDArray[np.float64]:
    """Rotation matrix about z by ``a`` radians (right-handed)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def quat_from_matrix(R: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit quaternion (x, y, z, w) with w ≥ 0 of a rotation matrix (Shepperd's method).

    Shapes:
        R: (3, 3) -> (4,)
    """
    tr = float(R[0, 0] + R[1, 1] + R[2, 2])
    if tr > 0.0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, s / 4]
    elif R[0, 0] >= R[1, 1] and R[0, 0] >= R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [s / 4, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s]
    elif R[1, 1] >= R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 1] + R[1, 0]) / s, s / 4, (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, s / 4, (R[1, 0] - R[0, 1]) / s]
    out = np.array(q, dtype=np.float64)
    out /= np.linalg.norm(out)
    return -out if out[3] < 0 else out


def _sigma(cfg: OdometryConfig, sigma_full: float, confidence: Mapping[str, float],
           key: str) -> float:
    c = float(confidence.get(key, 0.0))
    if not math.isfinite(c):
        c = 0.0
    return sigma_full / max(c, cfg.min_confidence)


def camera_pose(cfg: OdometryConfig, h: float, v: float, r: float, z: float | None,
                confidence: Mapping[str, float]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Camera pose relative to its first frame, in the optical convention.

    Args:
        cfg: The calibration.
        h, v: Camera position in the map, downsampled pixels.
        r: Roll about the optical axis, radians.
        z: Log scale, or None when the scale factor is off.
        confidence: Readout confidence per factor name (``'h'``, ``'v'``, ``'r'``, ``'z'``).

    Returns:
        position (3,) metres, rotation matrix (3, 3), covariance (6, 6) in the optical frame.
    """
    f = cfg.focal_length_px
    u = cfg.unobserved_variance
    s_h = _sigma(cfg, cfg.sigma_px, confidence, 'h') * cfg.scale
    s_v = _sigma(cfg, cfg.sigma_px, confidence, 'v') * cfg.scale
    s_r = _sigma(cfg, cfg.sigma_roll_rad, confidence, 'r')
    if cfg.motion_model == 'rotation':
        pan = math.atan(cfg.scale * h / f)
        tilt = -math.atan(cfg.scale * v / f)
        R = rot_y(pan) @ rot_x(tilt) @ rot_z(r)
        pos = np.zeros(3)
        # d atan(x/f)/dx = f / (f^2 + x^2)
        s_pan = s_h * f / (f * f + (cfg.scale * h) ** 2)
        s_tilt = s_v * f / (f * f + (cfg.scale * v) ** 2)
        diag = [u, u, u, s_tilt ** 2, s_pan ** 2, s_r ** 2]
    else:
        d = cfg.depth_m
        zz = 0.0 if z is None else z
        pos = np.array([cfg.scale * h * d / f, cfg.scale * v * d / f, d * (1.0 - math.exp(-zz))])
        R = rot_z(r)
        var_z = u if z is None else (d * math.exp(-zz)
                                     * _sigma(cfg, cfg.sigma_log_scale, confidence, 'z')) ** 2
        diag = [(s_h * d / f) ** 2, (s_v * d / f) ** 2, var_z, u, u, s_r ** 2]
    return pos, R, np.diag(np.asarray(diag, dtype=np.float64))


def readout_to_pose(cfg: OdometryConfig, t_ns: int, h: float, v: float, r: float,
                    z: float | None, confidence: Mapping[str, float]) -> OdomPose:
    """The odometry pose of ``cfg.child_frame`` for one readout (see the module docstring)."""
    pos, R, cov = camera_pose(cfg, h, v, r, z, confidence)
    if cfg.child_frame == 'base_link':
        B = R_BASE_OPTICAL
        pos = B @ pos
        R = B @ R @ B.T
        J = np.zeros((6, 6))
        J[:3, :3] = B
        J[3:, 3:] = B
        cov = J @ cov @ J.T
    return OdomPose(t_ns=int(t_ns), position=pos, quat=quat_from_matrix(R), covariance=cov)
