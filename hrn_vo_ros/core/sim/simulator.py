"""Event-camera simulator: a pinhole camera over a textured plane, with IMU and ground truth.

Public API::

    simulate(kind, seconds, *, seed, config=SimulatorConfig(), progress=None) -> Sequence
    KINDS = ('rotation', 'translation', 'arm')
    SimulatorConfig            # sensor, noise and rendering parameters (frozen dataclass)
    scene_for(kind, seed, seconds, config) -> Scene   # camera, texture and motion (demos)
    PLANE_Z[kind]                                     # the textured plane z = PLANE_Z (world)
    optical_axis_estimate(gt, plane_z) -> (h, v, r, z)   # ideal image registration (benchmarks)

The returned `Sequence` holds the events (int64 ns, sorted),
the calibration (with the sensor size), the IMU (1 kHz) and the ground truth (200 Hz).

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
from dataclasses import dataclass
import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from hrn_vo_ros.core.configbase import param, validate
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.camera import undistort_points
from hrn_vo_ros.core.events.sequence import CameraCalibration, ImuData, Sequence, Trajectory
from hrn_vo_ros.core.odometry.geometry import (
    euler_ptr_to_matrix,
    matrix_to_quat,
    matrix_to_swing_twist,
    quat_to_matrix,
    rot_z,
    so3_log,
)
from hrn_vo_ros.errors import ConfigError

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
Kind = Literal['rotation', 'translation', 'arm']
KINDS: tuple[str, ...] = ('rotation', 'translation', 'arm')
GRAVITY = 9.81
PLANE_Z: dict[str, float] = {'rotation': 1.0, 'translation': 0.8, 'arm': 0.0}
_LOG_EPS = 0.02


@dataclass(frozen=True, slots=True)
class SimulatorConfig:
    """Sensor, noise and rendering parameters of the simulator (scene and motion come from kind).
    """

    contrast_threshold: float = param(0.2, 'mean contrast threshold C (log intensity)',
                                      lo=0.02, hi=2.0)
    threshold_sigma: float = param(0.03, 'per-pixel, per-polarity std of C (mismatch)',
                                   lo=0.0, hi=0.5)
    min_threshold: float = param(0.05, 'lower clip of the per-pixel thresholds', lo=0.01, hi=1.0)
    refractory_s: float = param(1e-3, 'refractory period after an event, seconds',
                                lo=0.0, hi=0.1)
    noise_rate_hz: float = param(0.1, 'background-activity events per pixel per second',
                                 lo=0.0, hi=100.0)
    hot_pixels: int = param(3, 'number of hot pixels', lo=0, hi=10000)
    hot_pixel_rate_hz: float = param(150.0, 'mean event rate of a hot pixel, Hz', lo=0.0,
                                     hi=1e5)
    timestamp_resolution_s: float = param(1e-6, 'event timestamp quantum, seconds',
                                          lo=1e-9, hi=1e-3)
    max_px_per_render: float = param(0.5, 'largest image motion between renders, pixels',
                                     lo=0.05, hi=5.0)
    min_render_rate_hz: float = param(200.0, 'renders per second at least (slow motion)',
                                      lo=1.0, hi=1e6)
    speed_scale: float = param(1.0, 'multiplies all motion speeds (same amplitudes)',
                               lo=0.05, hi=10.0)
    lens_distortion: float = param(1.0, 'scales the scene preset lens distortion (0: pinhole)',
                                   lo=0.0, hi=3.0)
    imu_rate_hz: float = param(1000.0, 'IMU sample rate, Hz', lo=1.0, hi=1e5)
    gt_rate_hz: float = param(200.0, 'ground-truth (motion capture) rate, Hz', lo=1.0, hi=1e5)
    gyro_noise: float = param(3e-3, 'gyro white noise std per sample, rad/s', lo=0.0, hi=10.0)
    gyro_bias: float = param(5e-3, 'std of the constant gyro bias per axis, rad/s', lo=0.0,
                             hi=10.0)
    acc_noise: float = param(0.03, 'accelerometer white noise std per sample, m/s^2', lo=0.0,
                             hi=100.0)
    acc_bias: float = param(0.05, 'std of the constant accelerometer bias per axis, m/s^2',
                            lo=0.0, hi=100.0)
    render_batch: int = param(48, 'renders computed together at most (memory vs. speed)',
                              lo=1, hi=4096)
    render_pixels: int = param(1_000_000, 'pixels per render batch at most (cache size)',
                               lo=1, hi=1_000_000_000)

    def __post_init__(self) -> None:
        validate(self)


# ------------------------------------------------------------------------------------------
# Smooth random motion signals


class _Smooth:
    """A smooth random signal in [-1, 1]: a sum of sinusoids with a speed ramp and envelope.

    ``s(t) = env(t) * Σ a_k sin(2π f_k τ(t) + φ_k) / norm`` with ``τ' = g(t)`` rising linearly
    from ``g0`` to ``g1`` over the sequence (speed increases) and ``env`` from ``e0`` to 1.
    """

    def __init__(self, rng: np.random.Generator, seconds: float, *, f_lo: float, f_hi: float,
                 ramp: tuple[float, float, float], n: int = 3) -> None:
        g0, g1, e0 = ramp
        self.f = rng.uniform(f_lo, f_hi, n)
        self.phase = rng.uniform(0.0, 2 * np.pi, n)
        self.amp = rng.uniform(0.4, 1.0, n)
        self.T = max(seconds, 1e-3)
        self.g0, self.g1, self.e0 = g0, g1, e0
        self.norm = 1.0
        grid = np.linspace(0.0, self.T, 20001)
        self.norm = float(np.max(np.abs(self(grid)))) or 1.0

    def __call__(self, t: F64) -> F64:
        tc = np.clip(t, 0.0, self.T)
        tau = self.g0 * tc + 0.5 * (self.g1 - self.g0) * tc * tc / self.T
        # continue linearly before the start and past the end (smooth finite differences)
        tau = tau + np.where(t > tc, self.g1, self.g0) * (t - tc)
        env = self.e0 + (1.0 - self.e0) * tc / self.T
        s = np.sum(self.amp[:, None] * np.sin(2 * np.pi * self.f[:, None] * tau[None, :]
                                              + self.phase[:, None]), axis=0)
        return np.asarray(env * s / self.norm, dtype=np.float64)


Motion = Callable[[F64], tuple[F64, F64]]


class _RotationMotion:
    """Hand-held 3-DoF rotation about the camera centre (plus a few mm of hand translation)."""

    def __init__(self, rng: np.random.Generator, seconds: float, speed: float) -> None:
        deg = np.pi / 180.0
        ramp = (1.0 * speed, 9.0 * speed, 0.6)
        self.limits = (20 * deg * rng.uniform(0.85, 1.0), 20 * deg * rng.uniform(0.85, 1.0),
                       50 * deg * rng.uniform(0.85, 1.0))
        self.angles = [_Smooth(rng, seconds, f_lo=0.1, f_hi=0.4, ramp=ramp) for _ in range(3)]
        self.hand = [_Smooth(rng, seconds, f_lo=0.3, f_hi=1.2, ramp=(speed, 2 * speed, 1.0))
                     for _ in range(3)]

    def __call__(self, t: F64) -> tuple[F64, F64]:
        pan, tilt, roll = (lim * s(t) for lim, s in zip(self.limits, self.angles, strict=True))
        R = euler_ptr_to_matrix(pan, tilt, roll)
        c = np.stack([0.004 * s(t) for s in self.hand], axis=-1)
        return R, c


class _TranslationMotion:
    """x/y/z translation in front of the wall with a little roll and pan/tilt wobble."""

    def __init__(self, rng: np.random.Generator, seconds: float, speed: float) -> None:
        deg = np.pi / 180.0
        ramp = (1.0 * speed, 5.0 * speed, 0.6)
        self.amp = np.array([0.30, 0.22, 0.15]) * rng.uniform(0.85, 1.0, 3)
        self.pos = [_Smooth(rng, seconds, f_lo=0.1, f_hi=0.4, ramp=ramp) for _ in range(3)]
        self.roll_lim = 8 * deg * rng.uniform(0.8, 1.0)
        self.roll = _Smooth(rng, seconds, f_lo=0.1, f_hi=0.4, ramp=ramp)
        self.wobble = [_Smooth(rng, seconds, f_lo=0.2, f_hi=0.8, ramp=ramp) for _ in range(2)]

    def __call__(self, t: F64) -> tuple[F64, F64]:
        deg = np.pi / 180.0
        R = euler_ptr_to_matrix(0.5 * deg * self.wobble[0](t), 0.5 * deg * self.wobble[1](t),
                                self.roll_lim * self.roll(t))
        c = np.stack([a * s(t) for a, s in zip(self.amp, self.pos, strict=True)], axis=-1)
        return R, c


class _ArmMotion:
    """A camera on a robot arm facing down, swept along horizontal arcs about the arm base."""

    period = 6.0
    arc_time = 4.5
    start = 0.5

    def __init__(self, rng: np.random.Generator, seconds: float, speed: float) -> None:
        deg = np.pi / 180.0
        self.radius = 0.45
        self.height = 0.40
        self.phi0 = -25 * deg
        n_arcs = int(seconds / self.period) + 2
        self.sweeps = 50 * deg * rng.uniform(0.9, 1.0, n_arcs)
        self.speed = speed
        self.wobble = [_Smooth(rng, seconds, f_lo=0.5, f_hi=2.0, ramp=(1.0, 1.0, 1.0))
                       for _ in range(3)]
        # camera axes in the world for zero sweep: x_c = +x, y_c = -y, z_c = -z (looking down)
        self.R_down = np.diag([1.0, -1.0, -1.0])

    def phi(self, t: F64) -> F64:
        """Sweep angle of the arm (rad) at times ``t``."""
        ts = t * self.speed
        k = np.floor((ts - self.start) / self.period)
        u = ts - self.start - k * self.period
        kk = np.clip(k, 0, len(self.sweeps) - 1).astype(np.int64)
        active = (ts >= self.start) & (u < self.arc_time)
        prof = np.where(active, 0.5 * (1 - np.cos(2 * np.pi * u / self.arc_time)), 0.0)
        return np.asarray(self.phi0 + self.sweeps[kk] * prof, dtype=np.float64)

    def __call__(self, t: F64) -> tuple[F64, F64]:
        deg = np.pi / 180.0
        phi = self.phi(t)
        wob = euler_ptr_to_matrix(0.1 * deg * self.wobble[0](t), 0.1 * deg * self.wobble[1](t),
                                  0.0)
        R = rot_z(phi) @ self.R_down @ wob
        c = np.stack([self.radius * np.cos(phi), self.radius * np.sin(phi),
                      self.height + 0.001 * self.wobble[2](t)], axis=-1)
        return R, c


# ------------------------------------------------------------------------------------------
# Textures


@dataclass(frozen=True, slots=True)
class Texture:
    """Irradiance on the plane: ``image[row, col]`` at (x0 + col*texel, y0 + row*texel)."""

    image: F32
    x0: float
    y0: float
    texel: float
    outside: float


def _poly_mask(xx: F64, yy: F64, px: F64, py: F64) -> NDArray[np.bool_]:
    """Even-odd point-in-polygon test for grid points (vectorised over points)."""
    inside = np.zeros(xx.shape, dtype=bool)
    n = len(px)
    for i in range(n):
        x1, y1, x2, y2 = px[i], py[i], px[(i + 1) % n], py[(i + 1) % n]
        if y1 == y2:
            continue
        cond = (yy >= min(y1, y2)) & (yy < max(y1, y2))
        xc = x1 + (yy - y1) * (x2 - x1) / (y2 - y1)
        inside ^= cond & (xx < xc)
    return inside


def _shape_outline(rng: np.random.Generator, kind: str, size: float) -> tuple[F64, F64] | None:
    """Vertices (unrotated, centred) of a polygon-like shape, or None for an ellipse."""
    if kind == 'ellipse':
        return None
    if kind == 'star':
        k = int(rng.integers(4, 8))
        ang = np.arange(2 * k) * np.pi / k
        rad = np.where(np.arange(2 * k) % 2 == 0, size, size * rng.uniform(0.35, 0.55))
    elif kind == 'rect':
        a = size * rng.uniform(0.5, 1.0)
        b = size * rng.uniform(0.2, 1.0)
        return np.array([-a, a, a, -a]), np.array([-b, -b, b, b])
    else:  # regular-ish polygon
        k = int(rng.integers(3, 7))
        ang = np.arange(k) * 2 * np.pi / k + rng.uniform(-0.15, 0.15, k)
        rad = size * rng.uniform(0.85, 1.0, k)
    return rad * np.cos(ang), rad * np.sin(ang)


def _paint(img: F64, rng: np.random.Generator, x0: float, y0: float, texel: float,
           cx: float, cy: float, kind: str, size: float, value: float,
           angle: float | None = None, aspect: float | None = None) -> None:
    """Paint one filled shape of ``value`` onto ``img`` (in place)."""
    half = size * 1.05
    c0 = max(int((cx - half - x0) / texel), 0)
    c1 = min(int((cx + half - x0) / texel) + 2, img.shape[1])
    r0 = max(int((cy - half - y0) / texel), 0)
    r1 = min(int((cy + half - y0) / texel) + 2, img.shape[0])
    if c1 <= c0 or r1 <= r0:
        return
    cols = x0 + np.arange(c0, c1) * texel - cx
    rows = y0 + np.arange(r0, r1) * texel - cy
    xx, yy = np.meshgrid(cols, rows)
    th = rng.uniform(0, 2 * np.pi) if angle is None else angle
    xr = np.cos(th) * xx + np.sin(th) * yy
    yr = -np.sin(th) * xx + np.cos(th) * yy
    if kind == 'ellipse':
        asp = rng.uniform(0.45, 1.0) if aspect is None else aspect
        mask = (xr / size) ** 2 + (yr / (size * asp)) ** 2 <= 1.0
    else:
        outline = _shape_outline(rng, kind, size)
        assert outline is not None  # only ellipses have no outline
        mask = _poly_mask(xr, yr, outline[0], outline[1])
    img[r0:r1, c0:c1][mask] = value


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], sigma: float) -> F64:
    """Zero-mean, unit-std smooth noise (correlation length ``sigma`` texels).

    Large ``sigma`` is made on a coarse grid and interpolated (a full-size Gaussian filter with
    a wide kernel would take seconds).
    """
    step = max(int(sigma / 3), 1)
    coarse_shape = (shape[0] // step + 3, shape[1] // step + 3)
    n = ndimage.gaussian_filter(rng.standard_normal(coarse_shape), sigma / step, mode='wrap')
    if step > 1:
        n = ndimage.zoom(n, step, order=1)[:shape[0], :shape[1]]
    n = n[:shape[0], :shape[1]]
    return np.asarray((n - n.mean()) / max(float(n.std()), 1e-12), dtype=np.float64)


def shapes_texture(rng: np.random.Generator, *, half_extent: float, texel: float,
                   density: float, blur_m: float) -> Texture:
    """A poster wall: dark polygons, stars, rectangles and ellipses on an uneven light ground.

    Args:
        rng: Random generator.
        half_extent: Half the side of the square textured area, metres.
        texel: Texture resolution, metres.
        density: Shapes per square metre.
        blur_m: Optical blur (Gaussian std) in metres on the plane.
    """
    n = int(round(2 * half_extent / texel))
    x0 = y0 = -half_extent
    light = 0.8 * (1 + 0.06 * _smooth_noise(rng, (n, n), 0.25 / texel))
    img = light.copy()
    # stratified placement (a jittered grid, like a poster layout): the number of shapes in
    # view, and so the event rate, varies little from seed to seed
    cell = 1.0 / math.sqrt(density)
    centres = np.arange(-half_extent + cell / 2, half_extent, cell)
    kinds = ('poly', 'poly', 'star', 'ellipse', 'ellipse', 'rect')
    for gx, gy in ((a, b) for a in centres for b in centres):
        kind = kinds[int(rng.integers(len(kinds)))]
        size = float(rng.uniform(0.03, 0.08))
        cx, cy = np.array([gx, gy]) + rng.uniform(-0.4, 0.4, 2) * cell
        value = float(rng.choice([rng.uniform(0.06, 0.15), rng.uniform(0.15, 0.45)]))
        _paint(img, rng, x0, y0, texel, float(cx), float(cy), kind, size, value)
    img *= 1 + 0.01 * rng.standard_normal(img.shape)  # paper grain
    img = ndimage.gaussian_filter(img, blur_m / texel)
    return Texture(np.clip(img, 0.01, 1.0).astype(np.float32), x0, y0, texel, 0.8)


def table_texture(rng: np.random.Generator, *, x_range: tuple[float, float],
                  y_range: tuple[float, float], texel: float, blur_m: float) -> Texture:
    """A table top (wood grain) with a plate, bowl, cup, cutlery, napkin and placemat on a floor.
    """
    nx = int(round((x_range[1] - x_range[0]) / texel))
    ny = int(round((y_range[1] - y_range[0]) / texel))
    x0, y0 = x_range[0], y_range[0]
    xs = x0 + np.arange(nx) * texel
    ys = y0 + np.arange(ny) * texel
    X, Y = np.meshgrid(xs, ys)
    # floor everywhere, then the 0.75 m x 0.75 m table with wood grain along y
    img = 0.25 * (1 + 0.15 * _smooth_noise(rng, (ny, nx), 0.01 / texel))
    table = (X > 0.12) & (X < 0.87) & (np.abs(Y) < 0.375)
    warp = 0.01 * _smooth_noise(rng, (ny, nx), 0.05 / texel)
    grain = np.sin(2 * np.pi * (X + warp) / rng.uniform(0.006, 0.01))
    rings = np.sin(2 * np.pi * (X + 3 * warp) / 0.045)
    wood = 0.5 * (1 + 0.03 * grain + 0.06 * rings + 0.03 * _smooth_noise(rng, (ny, nx),
                                                                           0.002 / texel))
    img[table] = wood[table]

    def paint(cx: float, cy: float, kind: str, size: float, value: float,
              angle: float | None = None, aspect: float | None = None) -> None:
        _paint(img, rng, x0, y0, texel, cx, cy, kind, size, value, angle, aspect)

    def jitter(v: float, d: float = 0.04) -> float:
        return v + float(rng.uniform(-d, d))

    # placemat with a check pattern
    pm = (np.abs(X - jitter(0.45)) < 0.16) & (np.abs(Y - jitter(-0.12)) < 0.11)
    check = ((np.floor(X / 0.04) + np.floor(Y / 0.04)) % 2).astype(np.float64)
    img[pm] = (0.45 + 0.15 * check)[pm]
    # plate with a rim, bowl (dark ring, lighter inside), cup with handle
    px, py = jitter(0.45), jitter(-0.12)
    paint(px, py, 'ellipse', 0.11, 0.92, 0.0, 1.0)
    paint(px, py, 'ellipse', 0.085, 0.8, 0.0, 1.0)
    bx, by = jitter(0.62), jitter(0.15)
    paint(bx, by, 'ellipse', 0.08, 0.12, 0.0, 1.0)
    paint(bx, by, 'ellipse', 0.065, 0.45, 0.0, 1.0)
    paint(bx + 0.015, by - 0.01, 'ellipse', 0.03, 0.7, 0.3, 0.6)
    cx, cy = jitter(0.3), jitter(0.2)
    paint(cx + 0.045, cy, 'rect', 0.02, 0.2, 0.0)
    paint(cx, cy, 'ellipse', 0.04, 0.18, 0.0, 1.0)
    paint(cx, cy, 'ellipse', 0.03, 0.08, 0.0, 1.0)
    # cutlery: long thin bright blades with dark handles
    for k in range(3):
        ux, uy = jitter(0.64 + 0.035 * k, 0.01), jitter(-0.14, 0.02)
        ang = float(rng.uniform(-0.2, 0.2)) + np.pi / 2
        paint(ux, uy, 'rect', 0.09, 0.95, ang, None)
        paint(ux + 0.07 * np.cos(ang), uy + 0.07 * np.sin(ang), 'rect', 0.04, 0.1, ang)
    # napkin with stripes, a book, small items
    nx0, ny0 = jitter(0.22), jitter(-0.22)
    nap = (np.abs(X - nx0) < 0.07) & (np.abs(Y - ny0) < 0.07)
    img[nap] = (0.85 - 0.25 * (np.floor((X - nx0) / 0.012) % 3 == 0))[nap]
    paint(jitter(0.75), jitter(-0.3), 'rect', 0.1, 0.3, float(rng.uniform(0, np.pi)))
    for _ in range(12):
        paint(float(rng.uniform(0.15, 0.85)), float(rng.uniform(-0.36, 0.36)),
              ['poly', 'ellipse', 'star'][int(rng.integers(3))], float(rng.uniform(0.008, 0.025)),
              float(rng.uniform(0.05, 0.95)))
    img = ndimage.gaussian_filter(img, blur_m / texel)
    return Texture(np.clip(img, 0.01, 1.0).astype(np.float32), x0, y0, texel, 0.25)


# ------------------------------------------------------------------------------------------
# Scenes


@dataclass(frozen=True, slots=True)
class Scene:
    """Camera, textured plane z = ``plane_z`` (world) and camera motion of one simulated kind."""

    kind: str
    calib: CameraCalibration
    texture: Texture
    plane_z: float
    motion: Motion
    gravity: tuple[float, float, float]
    render_px_scale: float = 1.0


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
            motion = _RotationMotion(rng, seconds, cfg.speed_scale)
            texture = shapes_texture(rng, half_extent=2.0, texel=0.0025, density=6.5,
                                     blur_m=0.6 * footprint)
        else:
            motion = _TranslationMotion(rng, seconds, cfg.speed_scale)
            texture = shapes_texture(rng, half_extent=1.6, texel=0.002, density=12.0,
                                     blur_m=0.6 * footprint * 0.8)
        return Scene(kind, calib, texture, depth, motion, (0.0, GRAVITY, 0.0))
    f = 320.0 / math.tan(math.radians(35.0))
    calib = CameraCalibration(640, 480, f, f, 319.5, 239.5, (-0.04 * dist, 0.0, 0.0, 0.0, 0.0))
    texture = table_texture(rng, x_range=(-0.25, 1.15), y_range=(-0.75, 0.75), texel=0.0007,
                            blur_m=0.6 * 0.4 / f)
    # 640x480 is downsampled by 10 for the HRN: renders every 1 px (not 0.5) of motion suffice
    return Scene(kind, calib, texture, PLANE_Z['arm'], _ArmMotion(rng, seconds, cfg.speed_scale),
                 (0.0, 0.0, -GRAVITY), render_px_scale=2.0)


# ------------------------------------------------------------------------------------------
# Rendering and events


def _undistort_points(calib: CameraCalibration, u: F64, v: F64) -> tuple[F64, F64]:
    """Normalised undistorted coordinates of distorted pixel coordinates."""
    return undistort_points(calib.fx, calib.fy, calib.cx, calib.cy, calib.dist, u, v)


class _Renderer:
    """Log irradiance of every pixel for a batch of times."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        c = scene.calib
        vv, uu = np.mgrid[0:c.height, 0:c.width].astype(np.float64)
        x, y = _undistort_points(c, uu.ravel(), vv.ravel())
        self.rays = np.stack([x, y, np.ones_like(x)], axis=1)  # (N, 3) camera frame
        self.rays_t = np.ascontiguousarray(self.rays.T, dtype=np.float32)  # (3, N)
        self.log_tex = np.log(scene.texture.image + np.float32(_LOG_EPS)).astype(np.float32)
        self.log_flat = self.log_tex.ravel()
        # sparse probe points for the adaptive render rate
        gu, gv = np.meshgrid(np.linspace(0, c.width - 1, 9), np.linspace(0, c.height - 1, 7))
        px, py = _undistort_points(c, gu.ravel(), gv.ravel())
        self.probes = np.stack([px, py, np.ones_like(px)], axis=1)

    def plane_points(self, R: F64, c: F64, rays: F64) -> tuple[F64, F64]:
        """Plane coordinates hit by ``rays`` (camera frame) from poses (R, c).

        Shapes:
            R: (B, 3, 3); c: (B, 3); rays: (N, 3); returns two (B, N) arrays.
        """
        d = np.einsum('bij,nj->bni', R, rays)
        dz = d[..., 2]
        dz = np.where(np.abs(dz) < 1e-9, 1e-9, dz)
        lam = (self.scene.plane_z - c[:, 2, None]) / dz
        lam = np.maximum(lam, 0.0)
        return c[:, 0, None] + lam * d[..., 0], c[:, 1, None] + lam * d[..., 1]

    def render(self, t: F64) -> F32:
        """Log intensity ``log(I + 0.02)`` at times ``t``. Shapes: t (B,) -> (B, N) float32.

        The plane is mapped to the image by a homography per time: with ray r (camera frame),
        d = R r and lam = (z_plane - c_z) / d_z, the plane point is c + lam d, i.e.
        col = ((c_x - x0) d_z + (z_plane - c_z) d_x) / (texel d_z) (rows likewise): one small
        matrix product for all pixels and renders, then a bilinear texture lookup.
        """
        R, c = self.scene.motion(t)
        tex = self.scene.texture
        dz_w = self.scene.plane_z - c[:, 2]
        M = np.empty((len(t), 3, 3))
        M[:, 0] = ((c[:, 0] - tex.x0)[:, None] * R[:, 2] + dz_w[:, None] * R[:, 0]) / tex.texel
        M[:, 1] = ((c[:, 1] - tex.y0)[:, None] * R[:, 2] + dz_w[:, None] * R[:, 1]) / tex.texel
        M[:, 2] = R[:, 2]
        P = (M.reshape(-1, 3).astype(np.float32) @ self.rays_t).reshape(len(t), 3, -1)
        den = P[:, 2]
        den[np.abs(den) < 1e-6] = 1e-6
        col = P[:, 0] / den
        row = P[:, 1] / den
        return self._bilinear(row, col)

    def _bilinear(self, row: F32, col: F32) -> F32:
        """Bilinear lookup in the log texture (coordinates clamped to the texture)."""
        img = self.log_tex
        h, w = img.shape
        np.clip(col, 0, w - 1.001, out=col)
        np.clip(row, 0, h - 1.001, out=row)
        ic = col.astype(np.int32)
        ir = row.astype(np.int32)
        col -= ic
        row -= ir
        flat = ir * np.int32(w)
        flat += ic
        v00 = self.log_flat[flat]
        v01 = self.log_flat[flat + 1]
        flat += np.int32(w)
        v10 = self.log_flat[flat]
        v11 = self.log_flat[flat + 1]
        v01 -= v00
        v01 *= col
        v00 += v01
        v11 -= v10
        v11 *= col
        v10 += v11
        v10 -= v00
        v10 *= row
        v00 += v10
        return np.asarray(v00, dtype=np.float32)

    def motion_px(self, t: F64) -> F64:
        """Largest image motion (pixels) of the probe points between consecutive times.

        Shapes:
            t: (n,); returns (n - 1,).
        """
        R, c = self.scene.motion(t)
        X, Y = self.plane_points(R, c, self.probes)
        P = np.stack([X[:-1], Y[:-1], np.full_like(X[:-1], self.scene.plane_z)], axis=-1)
        cam = np.einsum('bji,bnj->bni', R[1:], P - c[1:, None, :])
        z = np.maximum(cam[..., 2], 1e-6)
        calib = self.scene.calib
        u = calib.fx * cam[..., 0] / z
        v = calib.fy * cam[..., 1] / z
        u0 = calib.fx * self.probes[:, 0]
        v0 = calib.fy * self.probes[:, 1]
        return np.asarray(np.max(np.hypot(u - u0, v - v0), axis=1), dtype=np.float64)


def _render_times(renderer: _Renderer, seconds: float, cfg: SimulatorConfig) -> F64:
    """Adaptive render times in [0, seconds]: ≤ max_px_per_render of motion between renders."""
    base_dt = 2.5e-4
    tb = np.linspace(0.0, seconds, int(math.ceil(seconds / base_dt)) + 1)
    step = np.empty(len(tb) - 1)
    for i0 in range(0, len(tb) - 1, 20000):
        seg = tb[i0:i0 + 20001]
        step[i0:i0 + len(seg) - 1] = renderer.motion_px(seg)
    cum = np.concatenate([[0.0], np.cumsum(step)])
    n_motion = int(math.ceil(cum[-1] / (cfg.max_px_per_render
                                        * renderer.scene.render_px_scale)))
    t_motion = np.interp(np.linspace(0.0, cum[-1], n_motion + 1), cum, tb)
    t_min = np.linspace(0.0, seconds, int(math.ceil(seconds * cfg.min_render_rate_hz)) + 1)
    t = np.unique(np.concatenate([t_motion, t_min]))
    # drop renders closer than 2 µs (identical images)
    keep = np.concatenate([[True], np.diff(t) > 2e-6])
    t = np.asarray(t[keep], dtype=np.float64)
    t[-1] = seconds
    return t


class _EventGenerator:
    """Per-pixel contrast-threshold crossing with mismatch and a refractory period."""

    def __init__(self, n_pix: int, cfg: SimulatorConfig, rng: np.random.Generator,
                 L0: F32) -> None:
        c = cfg.contrast_threshold
        self.c_on = np.maximum(rng.normal(c, cfg.threshold_sigma, n_pix), cfg.min_threshold)
        self.c_off = np.maximum(rng.normal(c, cfg.threshold_sigma, n_pix), cfg.min_threshold)
        # arbitrary reset state at the start: the reference sits somewhere inside its band
        self.ref = L0.astype(np.float64) + rng.uniform(-0.5, 0.5, n_pix) * np.minimum(
            self.c_on, self.c_off)
        self.last = np.full(n_pix, -1.0)
        self.refr = cfg.refractory_s

    def step(self, L0: F32, L1: F32, t0: float, t1: float,
             out: list[tuple[NDArray[np.intp], F64, NDArray[np.bool_]]]) -> None:
        """Emit the events of the interval (t0, t1] where log intensity goes from L0 to L1."""
        d = L1 - self.ref
        pos = d >= self.c_on
        neg = d <= -self.c_off
        idx = np.flatnonzero(pos | neg)
        if idx.size == 0:
            return
        up = pos[idx]
        sgn = np.where(up, 1.0, -1.0)
        C = np.where(up, self.c_on[idx], self.c_off[idx])
        n = np.floor(np.abs(d[idx]) / C).astype(np.int64)
        l0 = L0[idx].astype(np.float64)
        dl = L1[idx].astype(np.float64) - l0
        dl = np.where(np.abs(dl) < 1e-12, 1e-12, dl)
        base = self.ref[idx]
        dt = t1 - t0
        sel_idx, sel_sgn, sel_C, sel_base, sel_l0, sel_dl = idx, sgn, C, base, l0, dl
        sel_n = n
        for k in range(1, int(n.max()) + 1):
            if k > 1:
                m = sel_n >= k
                sel_idx, sel_sgn, sel_C = sel_idx[m], sel_sgn[m], sel_C[m]
                sel_base, sel_l0, sel_dl, sel_n = sel_base[m], sel_l0[m], sel_dl[m], sel_n[m]
            level = sel_base + sel_sgn * k * sel_C
            frac = np.clip((level - sel_l0) / sel_dl, 0.0, 1.0)
            tk = t0 + frac * dt
            ok = tk - self.last[sel_idx] >= self.refr
            if np.any(ok):
                pix = sel_idx[ok]
                self.last[pix] = tk[ok]
                out.append((pix, tk[ok], sel_sgn[ok] > 0))
        self.ref[idx] = base + sgn * n * C


def _noise_events(rng: np.random.Generator, n_pix: int, hot: NDArray[np.intp],
                  hot_rates: F64, t0: float, t1: float,
                  cfg: SimulatorConfig) -> tuple[NDArray[np.intp], F64, NDArray[np.bool_]]:
    """Background activity and hot-pixel events in (t0, t1]."""
    dur = t1 - t0
    n_ba = int(rng.poisson(cfg.noise_rate_hz * n_pix * dur))
    pix = [rng.integers(0, n_pix, n_ba)]
    counts = rng.poisson(hot_rates * dur)
    pix.append(np.repeat(hot, counts))
    allpix = np.concatenate(pix).astype(np.intp)
    t = t1 - rng.uniform(0.0, dur, allpix.size)
    pol = rng.random(allpix.size) < 0.5
    return allpix, t, pol


def _imu_and_gt(scene: Scene, seconds: float, cfg: SimulatorConfig,
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
    rng = np.random.default_rng([seed, 1])
    renderer = _Renderer(scene)
    times = _render_times(renderer, seconds, cfg)
    calib = scene.calib
    n_pix = calib.width * calib.height
    L_prev = renderer.render(times[:1])[0]
    gen = _EventGenerator(n_pix, cfg, rng, L_prev)
    hot = rng.choice(n_pix, size=min(cfg.hot_pixels, n_pix), replace=False).astype(np.intp)
    hot_rates = cfg.hot_pixel_rate_hz * rng.uniform(0.3, 2.0, hot.size)
    quantum = cfg.timestamp_resolution_s
    parts_t: list[NDArray[np.int64]] = []
    parts_pix: list[NDArray[np.intp]] = []
    parts_p: list[NDArray[np.bool_]] = []
    B = max(1, min(cfg.render_batch, cfg.render_pixels // n_pix))
    done = 0.0
    for b0 in range(1, len(times), B):
        tb = times[b0:b0 + B]
        Ls = renderer.render(tb)
        out: list[tuple[NDArray[np.intp], F64, NDArray[np.bool_]]] = []
        t_prev = float(times[b0 - 1])
        for j in range(len(tb)):
            gen.step(L_prev, Ls[j], t_prev, float(tb[j]), out)
            L_prev = Ls[j]
            t_prev = float(tb[j])
        out.append(_noise_events(rng, n_pix, hot, hot_rates, float(times[b0 - 1]),
                                 float(tb[-1]), cfg))
        pix = np.concatenate([o[0] for o in out])
        ts = np.concatenate([o[1] for o in out])
        pol = np.concatenate([o[2] for o in out])
        tq = (np.floor(ts / quantum + 1e-6) * (quantum * 1e9)).astype(np.int64)
        order = np.argsort(tq, kind='stable')
        parts_t.append(tq[order])
        parts_pix.append(pix[order])
        parts_p.append(pol[order])
        if progress is not None:
            progress(float(tb[-1]) - done)
            done = float(tb[-1])
    t_all = np.concatenate(parts_t) if parts_t else np.empty(0, np.int64)
    pix_all = np.concatenate(parts_pix) if parts_pix else np.empty(0, np.intp)
    p_all = np.concatenate(parts_p) if parts_p else np.empty(0, bool)
    events = EventArray.from_arrays(t_all, pix_all % calib.width, pix_all // calib.width,
                                    p_all.astype(np.uint8))
    imu, gt = _imu_and_gt(scene, seconds, cfg, np.random.default_rng([seed, 2]))
    return Sequence(events=events, calib=calib, imu=imu, groundtruth=gt)


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
