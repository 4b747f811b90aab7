"""Event-camera simulator: a pinhole camera over a textured plane, with IMU and ground truth.

Public API::

    simulate(kind, seconds, *, seed, config=SimulatorConfig(), progress=None) -> Sequence
    KINDS = ('rotation', 'translation', 'arm')
    SimulatorConfig            # sensor, noise and rendering parameters (frozen dataclass)
    scene_for(kind, seed, seconds, config) -> Scene   # camera, texture and motion (demos)
    PLANE_Z[kind]                                     # the textured plane z = PLANE_Z (world)
    optical_axis_estimate(gt, plane_z) -> (h, v, r, z)   # ideal image registration (benchmarks)

The returned `Sequence` holds the events (int64 ns, sorted),
the calibration (with the sensor size), the IMU (1 kHz) and the ground truth (1 kHz; `gt_rate_hz`).

Scenes (``kind``):

* ``rotation`` (like the Event Camera Dataset's shapes_rotation): DAVIS240C 240x180,
  fx ≈ fy ≈ 199 px, a wall 1 m away covered with high-contrast polygons, stars and ellipses on a
  light, unevenly lit background; hand-held 3-DoF rotation about the camera centre (roll up to
  ±50°, pan/tilt up to ±20°, a few mm of hand translation), slow at the start and up to several
  hundred °/s at the end of the sequence; ≈ 3.5e5 events/s on average over 20 s.
* ``translation`` (like shapes_translation): the same camera and kind of wall 0.8 m away, x/y
  translation of ±0.3/±0.22 m, depth changes of ±0.15 m (image scale ±20 %), roll up to ±8° and
  ±0.5° of pan/tilt wobble; speeds up to ≈ 2.5 m/s at the end.
* ``arm``: a 640x480 Prophesee-like sensor (70° horizontal field of view) on a robot arm
  0.4 m above a table (wood grain, plate, bowl, cup, cutlery, napkin, placemat); the arm sweeps
  the camera along a horizontal arc of radius 0.45 m back and forth (one out-and-back arc of
  4.5 s every 6 s, starting at 0.5 s, ±25° of sweep, which also rolls the camera by 50°), with
  mm-level wobble in height and tilt.

Frames and conventions (Event Camera Dataset): camera x right, y down, z forward; ground truth
``t px py pz qx qy qz qw`` is the camera pose (camera-to-world rotation). For ``rotation`` and
``translation`` the world frame is the camera frame of the zero pose (the wall is the plane
z = d, gravity along +y); for ``arm`` the world has z up, the table is the plane z = 0 and
gravity is along -z. The IMU frame is the camera frame: gyro = body angular velocity ω with
dR/dt = R [ω]x (rad/s), accelerometer = specific force R^T (a - g) (m/s^2), both with white
noise and a constant bias per axis.

Event model (per pixel, as in ESIM / the DVS pixel): the log intensity L = log(I + 0.02) of the
rendered irradiance is compared with the pixel's reference level; each crossing of
reference ± C_on/off emits an event at the time linearly interpolated between renders, and moves
the reference by one threshold. C_on and C_off are drawn once per pixel from N(C, σ)
(mismatch). Within the refractory period after an event a pixel emits nothing (the crossings
are consumed, the reference still advances). Renders happen at an adaptive rate so that no image
point moves more than ``max_px_per_render`` between renders (twice that for the 640x480 arm
sensor, which is downsampled by 10 later). Background-activity events
(Poisson, per pixel) and a few hot pixels are added; timestamps are quantised to 1 µs. Lens
distortion (radial-tangential, the coefficients written to ``calib.txt``) is applied when
``lens_distortion`` > 0.

Everything random comes from ``np.random.default_rng(seed)``: same seed, same sequence.
"""

from __future__ import annotations

from collections.abc import Callable
import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.sequence import CameraCalibration, ImuData, Sequence, Trajectory
from hrn_vo_ros.core.odometry.geometry import (
    matrix_to_quat,
    matrix_to_swing_twist,
    quat_to_matrix,
    so3_log,
)
from hrn_vo_ros.core.sim.config import GRAVITY, Kind, KINDS, PLANE_Z, SimulatorConfig
from hrn_vo_ros.core.sim.motion import ArmMotion, Motion, RotationMotion, TranslationMotion
from hrn_vo_ros.core.sim.render import Scene, simulate_events
from hrn_vo_ros.core.sim.textures import shapes_texture, table_texture, Texture
from hrn_vo_ros.errors import ConfigError

__all__ = ['describe_motion', 'GRAVITY', 'Kind', 'KINDS', 'optical_axis_estimate', 'PLANE_Z',
           'Scene', 'scene_for', 'simulate', 'simulate_scene', 'SimulatorConfig', 'Texture']

F64 = NDArray[np.float64]


def scene_for(kind: str, seed: int, seconds: float,
              config: SimulatorConfig | None = None) -> Scene:
    """The scene (camera, texture, motion) that :func:`simulate` uses for ``kind`` and ``seed``.

    Raises:
        ConfigError: for an unknown kind or a non-positive duration.
    """
    cfg = SimulatorConfig() if config is None else config
    if kind not in KINDS:
        raise ConfigError(f'unknown simulation kind {kind!r}; use one of {", ".join(KINDS)}')
    if not seconds > 0:
        raise ConfigError(f'seconds = {seconds} must be positive')
    rng = np.random.default_rng([seed, 0])
    dist = cfg.lens_distortion
    if kind in ('rotation', 'translation'):
        calib = CameraCalibration(240, 180, 199.1, 198.8, 121.3, 89.6,
                                  (-0.12 * dist, 0.03 * dist, 0.0, 0.0, 0.0))
        depth = PLANE_Z[kind]
        footprint = depth / 199.0
        motion: Motion
        if kind == 'rotation':
            motion = RotationMotion(rng, seconds, cfg.speed_scale)
            texture = shapes_texture(rng, half_extent=2.0, texel=0.0025, density=6.5,
                                     blur_m=0.6 * footprint)
        else:
            motion = TranslationMotion(rng, seconds, cfg.speed_scale)
            texture = shapes_texture(rng, half_extent=1.6, texel=0.002, density=12.0,
                                     blur_m=0.6 * footprint * 0.8)
        return Scene(kind, calib, texture, depth, motion, (0.0, GRAVITY, 0.0))
    f = 320.0 / math.tan(math.radians(35.0))
    calib = CameraCalibration(640, 480, f, f, 319.5, 239.5, (-0.04 * dist, 0.0, 0.0, 0.0, 0.0))
    texture = table_texture(rng, x_range=(-0.25, 1.15), y_range=(-0.75, 0.75), texel=0.0007,
                            blur_m=0.6 * 0.4 / f)
    # 640x480 is downsampled by 10 for the HRN: renders every 1 px (not 0.5) of motion suffice
    return Scene(kind, calib, texture, PLANE_Z['arm'], ArmMotion(rng, seconds, cfg.speed_scale),
                 (0.0, 0.0, -GRAVITY), render_px_scale=2.0)


def imu_and_gt(scene: Scene, seconds: float, cfg: SimulatorConfig,
               rng: np.random.Generator) -> tuple[ImuData, Trajectory]:
    """IMU samples (noisy, biased) and ground-truth poses from the analytic motion."""
    motion = scene.motion
    t_imu = np.arange(0.0, seconds + 1e-12, 1.0 / cfg.imu_rate_hz)
    h = 1e-4
    Rm, _ = motion(t_imu - h)
    Rp, _ = motion(t_imu + h)
    gyro = so3_log(np.swapaxes(Rm, 1, 2) @ Rp) / (2 * h)
    ha = 2e-3
    R, c = motion(t_imu)
    _, cm = motion(t_imu - ha)
    _, cp = motion(t_imu + ha)
    acc_w = (cp - 2 * c + cm) / (ha * ha)
    g = np.asarray(scene.gravity)
    acc = np.einsum('nji,nj->ni', R, acc_w - g)
    gyro = gyro + rng.normal(0, cfg.gyro_bias, 3) + rng.normal(0, cfg.gyro_noise, gyro.shape)
    acc = acc + rng.normal(0, cfg.acc_bias, 3) + rng.normal(0, cfg.acc_noise, acc.shape)
    imu = ImuData(np.round(t_imu * 1e9).astype(np.int64), acc, gyro)
    t_gt = np.arange(0.0, seconds + 1e-12, 1.0 / cfg.gt_rate_hz)
    Rg, cg = motion(t_gt)
    gt = Trajectory(np.round(t_gt * 1e9).astype(np.int64), cg, matrix_to_quat(Rg))
    return imu, gt


def simulate(kind: str, seconds: float, *, seed: int, config: SimulatorConfig | None = None,
             progress: Callable[[float], None] | None = None) -> Sequence:
    """Simulate a sequence of ``kind`` lasting ``seconds`` (events, calibration, IMU, GT).

    Args:
        kind: ``'rotation'``, ``'translation'`` or ``'arm'`` (see the module docstring).
        seconds: Duration, seconds (events in (0, seconds]).
        seed: Seeds everything (texture, motion, thresholds, noise, IMU noise).
        config: Sensor/noise/rendering parameters.
        progress: Called with the number of simulated seconds completed since the last call.

    Returns:
        The sequence; events sorted by time, timestamps quantised to
        ``config.timestamp_resolution_s``.

    Raises:
        ConfigError: for an unknown kind or a non-positive duration.
    """
    cfg = SimulatorConfig() if config is None else config
    scene = scene_for(kind, seed, seconds, cfg)
    return simulate_scene(scene, seconds, seed=seed, config=cfg, progress=progress)


def simulate_scene(scene: Scene, seconds: float, *, seed: int,
                   config: SimulatorConfig | None = None,
                   progress: Callable[[float], None] | None = None) -> Sequence:
    """Simulate the events, IMU and ground truth of a given scene (any camera, texture, motion).

    Args:
        scene: Camera, textured plane and motion (:func:`scene_for`, or a randomized draw of
            :mod:`hrn_vo_ros.core.sim.family`).
        seconds: Duration, seconds (events in (0, seconds]).
        seed: Seeds the thresholds, noise events and IMU noise (``[seed, 1]``, ``[seed, 2]``).
        config: Sensor/noise/rendering parameters.
        progress: As for :func:`simulate`.

    Returns:
        The sequence (as :func:`simulate`).

    Raises:
        ConfigError: for a non-positive duration.
    """
    if not seconds > 0:
        raise ConfigError(f'seconds = {seconds} must be positive')
    cfg = SimulatorConfig() if config is None else config
    events = simulate_events(scene, seconds, cfg, np.random.default_rng([seed, 1]), progress)
    imu, gt = imu_and_gt(scene, seconds, cfg, np.random.default_rng([seed, 2]))
    return Sequence(events=events, calib=scene.calib, imu=imu, groundtruth=gt)


def describe_motion(seq: Sequence) -> dict[str, float]:
    """Summary figures of a simulated sequence (for CLI summaries and tests).

    Returns:
        events, events_per_s, on_fraction, peak and median angular speed (deg/s) from the
        ground truth, peak linear speed (m/s) and the path length (m).
    """
    ev = seq.events
    dur = 0.0
    gt = seq.groundtruth
    out: dict[str, float] = {'events': float(len(ev))}
    if gt is not None and len(gt) > 1:
        dur = (gt.t[-1] - gt.t[0]) * 1e-9
        R = quat_to_matrix(gt.quat)
        dt = np.diff(gt.t) * 1e-9
        w = np.linalg.norm(so3_log(np.swapaxes(R[:-1], 1, 2) @ R[1:]), axis=1) / dt
        v = np.linalg.norm(np.diff(gt.pos, axis=0), axis=1) / dt
        out.update(peak_deg_s=float(np.degrees(w.max())),
                   median_deg_s=float(np.degrees(np.median(w))),
                   peak_m_s=float(v.max()), path_m=float(np.sum(v * dt)))
    out['events_per_s'] = len(ev) / dur if dur > 0 else float('nan')
    out['on_fraction'] = float(np.mean(ev.p)) if len(ev) else float('nan')
    return out


def optical_axis_estimate(gt: Trajectory, plane_z: float) -> tuple[F64, F64, F64, F64]:
    """What an ideal image-registration estimator reads: the plane point on the optical axis.

    A frame registered against a planar map (shift, roll and zoom about the image centre)
    tells where the optical axis meets the plane, how the camera turns about that axis and
    how far the plane is, but not the camera position itself: a small pan or tilt moves the
    image like a sideways translation. Fed through the evaluation protocol, this estimate gives
    the error floor that no image-based estimator can beat (in ``translation`` the ±0.5°
    pan/tilt wobble moves the image by up to ~0.7 frame pixels, ~0.7 cm on the wall).

    Args:
        gt: Ground-truth camera poses (camera-to-world), with at least one pose.
        plane_z: The textured plane z = ``plane_z`` in world coordinates (:data:`PLANE_Z`).

    Returns:
        ``h, v``: the axis point on the plane in the first camera's x/y axes (metres, from the
        first pose's axis point); ``r``: twist about the optical axis relative to the first
        pose (rad, unwrapped); ``z``: log magnification ``-log(distance / first distance)``.
        Each of shape (n,).
    """
    R = quat_to_matrix(gt.quat)
    c = np.asarray(gt.pos, dtype=np.float64)
    axis = R[:, :, 2]                                   # optical axis (camera z) in the world
    az = np.where(np.abs(axis[:, 2]) < 1e-9, 1e-9, axis[:, 2])
    dist = (plane_z - c[:, 2]) / az                     # along the unit axis
    P = c + dist[:, None] * axis
    rel = (P - P[:1]) @ R[0]                            # R0^T (P - P0), first camera axes
    _, _, roll = matrix_to_swing_twist(np.swapaxes(R[:1], 1, 2) @ R)
    z = -np.log(np.abs(dist) / abs(float(dist[0])))
    return rel[:, 0], rel[:, 1], np.unwrap(roll), z
