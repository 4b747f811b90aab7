"""A randomized simulator family: per seed, a scene, camera, sensor, motion and IMU as real
recordings vary them.

Public API::

    draw(kind, seed) -> Draw           # the parameters of one randomized sequence
    preset('shapes_rotation', seed=0) -> Draw   # like the Event Camera Dataset's sequence
    simulate_draw(d, seconds=None, *, progress=None) -> Sequence
    scene_of(d, seconds) -> Scene
    split_of(seed) -> 'tuning' | 'reserved' | 'fresh'
    tuning_seeds(n), fresh_seeds(n)    # the first n seeds of each split
    RANGES                             # the documented range of every drawn number

**Splits.** Seeds 0-99 (:data:`TUNING`) are the *tuning* draws: tune and debug on these only.
Seeds from 10000 on (:data:`FRESH_START`) are the *fresh* (report) draws: figures for reports
come from these, never looked at while tuning. Seeds 100-9999 are *reserved* (tests, ad-hoc
runs); they draw like the others. The split is by seed only, the same for every kind.

**What is drawn** (everything from ``np.random.default_rng([seed, 7, kind index])``; ranges in
:data:`RANGES`; ``U`` uniform, ``logU`` log-uniform):

* scene (rotation, translation): ``shapes`` (a poster of dark and grey shapes, density
  3-25 per m², sizes 1.5-12 cm, contrast 0.3-0.95; p = 0.4), ``sparse`` (0.3-2 shapes per m²,
  p = 0.15), ``textured`` (multi-scale noise of 0.8-6 cm, flat to slightly red spectrum,
  log-intensity std 0.15-0.6; p = 0.25), ``natural`` (1/f-like noise of 1-50 cm with 1-6
  layers of sharp-edged patches; p = 0.2). Sizes are those at 1 m: the poster scales with the
  drawn distance (rotation 0.7-3 m, translation 0.5-1.5 m), so the image statistics do not
  depend on it, only the parallax does. arm: the laid table of :func:`scene_for`.
* camera: DAVIS240C-like 240x180 with fx 190-210 px, fy = fx (±0.5 %), the principal point
  off-centre by up to ±15 / ±22 px (the real calibration: +12.7, +21.2), half of the draws with
  radial-tangential distortion (k1 -0.40 to -0.05, k2 = |k1| · 0.1-0.45, |p1|, |p2| < 5e-4;
  the real one: k1 -0.368, k2 0.151), the others without. arm: 640x480, 65-75° horizontal
  field of view, centre within ±3 %, k1 -0.15 to 0 on half of the draws.
* sensor: contrast threshold 0.12-0.45, its per-pixel spread 0-30 % of it, refractory period
  logU 20 µs-2 ms, background activity logU 0.01-1 Hz per pixel, 0-30 hot pixels at
  a nominal logU 30-1000 Hz (each 0.3-2.0 times it: ``HOT_RATE_RANGE``).
* motion (rotation, translation): amplitude ramping from 20-80 % to 100 % and speed rising
  2-9x over the sequence (as in the Event Camera Dataset), smooth (p = 0.6) or jerky (a faster
  component of 10-35 %), 0-3 pauses of 0.3-1.5 s, peak angular speed logU 20-700 deg/s
  (rotation; pan/tilt limits 10-30°, roll 20-60°, hand translation 0-1 cm) or peak linear speed
  logU 0.2-2.5 m/s (translation; x 0.1-0.35 m, y 0.08-0.25 m, z 0-0.3 of the distance, roll
  2-15°, pan/tilt wobble 0.2-1.5°). arm: the arm's arcs at 0.6-1.6x their speed.
* IMU: gyro noise logU 1e-3-1e-2 rad/s, gyro bias std 0-0.02 rad/s, accelerometer noise
  logU 0.01-0.1 m/s², bias std 0-0.15 m/s².

The draw holds the parameters; the texture and the motion's waves come from
``[seed, 8, kind index]``, the events and IMU noise from ``[seed, 1]`` and ``[seed, 2]``
(:func:`~hrn_vo_ros.core.sim.simulator.simulate_scene`). Same seed, same sequence.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
import math
from typing import Literal

import numpy as np

from hrn_vo_ros.core.events.sequence import CameraCalibration, Sequence
from hrn_vo_ros.core.sim.config import GRAVITY, KINDS, SimulatorConfig
from hrn_vo_ros.core.sim.motion import ArmMotion, Progress, RampedMotion
from hrn_vo_ros.core.sim.render import Scene
from hrn_vo_ros.core.sim.simulator import simulate_scene
from hrn_vo_ros.core.sim.textures import natural_texture, shapes_texture, table_texture, Texture
from hrn_vo_ros.errors import ConfigError

Split = Literal['tuning', 'reserved', 'fresh']
TUNING = range(0, 100)
FRESH_START = 10_000
SCENE_KINDS = ('shapes', 'sparse', 'textured', 'natural')
_SCENE_P = (0.4, 0.15, 0.25, 0.2)
DEFAULT_SECONDS = 15.0
PRESETS = ('shapes_rotation',)
_DEG = math.pi / 180.0

#: The range of every drawn number, (lo, hi) inclusive: the documented family.
RANGES: dict[str, tuple[float, float]] = {
    'fx': (190.0, 210.0), 'fy_ratio': (0.995, 1.005), 'cx_offset': (-15.0, 15.0),
    'cy_offset': (-22.0, 22.0), 'k1': (-0.40, -0.05), 'k2_ratio': (0.1, 0.45),
    'p12': (-5e-4, 5e-4),
    'arm_hfov_deg': (65.0, 75.0), 'arm_centre_frac': (-0.03, 0.03), 'arm_k1': (-0.15, 0.0),
    'contrast_threshold': (0.12, 0.45), 'threshold_spread': (0.0, 0.3),
    'refractory_s': (2e-5, 2e-3), 'noise_rate_hz': (0.01, 1.0), 'hot_pixels': (0, 30),
    'hot_pixel_rate_hz': (30.0, 1000.0),
    'gyro_noise': (1e-3, 1e-2), 'gyro_bias': (0.0, 0.02), 'acc_noise': (0.01, 0.1),
    'acc_bias': (0.0, 0.15),
    'depth_rotation': (0.7, 3.0), 'depth_translation': (0.5, 1.5),
    'density': (3.0, 25.0), 'sparse_density': (0.3, 2.0), 'size_lo': (0.015, 0.04),
    'size_ratio': (1.5, 3.0), 'light': (0.5, 0.9), 'contrast': (0.3, 0.95),
    'texture_contrast': (0.15, 0.6), 'slope_textured': (0.0, 0.6), 'slope_natural': (0.7, 1.2),
    'patches': (1, 6), 'patch_contrast': (0.3, 1.2),
    'env0': (0.2, 0.8), 'speed_ratio': (2.0, 9.0), 'jerk': (0.1, 0.35), 'pauses': (0, 3),
    'pause_s': (0.3, 1.5), 'peak_deg_s': (20.0, 700.0), 'pan_tilt_deg': (10.0, 30.0),
    'roll_deg': (20.0, 60.0), 'hand_m': (0.0, 0.01), 'peak_m_s': (0.2, 2.5),
    'x_m': (0.1, 0.35), 'y_m': (0.08, 0.25), 'z_frac': (0.0, 0.3), 'trans_roll_deg': (2.0, 15.0),
    'wobble_deg': (0.2, 1.5), 'arm_speed': (0.6, 1.6),
}


@dataclass(frozen=True, slots=True)
class Draw:
    """The parameters of one randomized sequence (see the module docstring).

    Attributes:
        kind: ``'rotation'``, ``'translation'`` or ``'arm'``.
        seed: The seed it was drawn from (also seeds texture, waves, events, IMU noise).
        split: ``'tuning'``, ``'reserved'`` or ``'fresh'`` (:func:`split_of`); ``'preset'``
            for :func:`preset`.
        seconds: Default duration, seconds.
        scene: Scene kind (:data:`SCENE_KINDS`, or ``'table'`` for the arm).
        depth_m: Distance of the textured plane, metres.
        calib: Camera intrinsics and distortion (with the sensor size).
        config: Sensor, noise and IMU parameters of the simulator.
        texture: Texture parameters (sizes at 1 m).
        motion: Motion parameters (``style`` 0 smooth / 1 jerky, ``peak`` in deg/s or m/s, ...).
        pauses: Pauses ``(start, duration)`` as fractions of the duration / seconds.
    """

    kind: str
    seed: int
    split: str
    seconds: float
    scene: str
    depth_m: float
    calib: CameraCalibration
    config: SimulatorConfig
    texture: dict[str, float] = field(default_factory=dict)
    motion: dict[str, float] = field(default_factory=dict)
    pauses: tuple[tuple[float, float], ...] = ()

    def summary(self) -> str:
        """One line: scene, camera, sensor and motion figures."""
        c, s, m = self.calib, self.config, self.motion
        peak = (f'{m["peak"]:.0f} deg/s' if self.kind == 'rotation' else
                f'{m["peak"]:.2f} m/s' if self.kind == 'translation' else
                f'x{m["speed"]:.2f}')
        return (f'{self.kind} seed {self.seed} ({self.split}): {self.scene} at '
                f'{self.depth_m:.2f} m, c=({c.cx:.1f}, {c.cy:.1f}) k1 {c.dist[0]:+.2f}, '
                f'C {s.contrast_threshold:.2f}±{s.threshold_sigma:.2f}, refr '
                f'{1e3 * s.refractory_s:.2f} ms, noise {s.noise_rate_hz:.2f} Hz, hot '
                f'{s.hot_pixels}, peak {peak}, '
                f'{"jerky" if m.get("style", 0) else "smooth"}, {len(self.pauses)} pauses')


def split_of(seed: int) -> Split:
    """Which split ``seed`` belongs to (module docstring)."""
    if seed in TUNING:
        return 'tuning'
    return 'fresh' if seed >= FRESH_START else 'reserved'


def tuning_seeds(n: int) -> list[int]:
    """The first ``n`` tuning seeds (at most 100)."""
    if not 0 <= n <= len(TUNING):
        raise ConfigError(f'{n} tuning draws: there are {len(TUNING)} (seeds 0-99)')
    return list(TUNING[:n])


def fresh_seeds(n: int, start: int = 0) -> list[int]:
    """``n`` fresh (report) seeds, from ``FRESH_START + start``."""
    return list(range(FRESH_START + start, FRESH_START + start + n))


def _kind_index(kind: str) -> int:
    if kind not in KINDS:
        raise ConfigError(f'unknown simulation kind {kind!r}; use one of {", ".join(KINDS)}')
    return KINDS.index(kind)


def _logu(rng: np.random.Generator, key: str) -> float:
    lo, hi = RANGES[key]
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _u(rng: np.random.Generator, key: str) -> float:
    lo, hi = RANGES[key]
    return float(rng.uniform(lo, hi))


def _int(rng: np.random.Generator, key: str) -> int:
    lo, hi = RANGES[key]
    return int(rng.integers(int(lo), int(hi) + 1))


def _sensor(rng: np.random.Generator) -> SimulatorConfig:
    c = _u(rng, 'contrast_threshold')
    return SimulatorConfig(
        contrast_threshold=c, threshold_sigma=c * _u(rng, 'threshold_spread'),
        min_threshold=min(0.05, 0.5 * c), refractory_s=_logu(rng, 'refractory_s'),
        noise_rate_hz=_logu(rng, 'noise_rate_hz'),
        hot_pixels=_int(rng, 'hot_pixels'),
        hot_pixel_rate_hz=_logu(rng, 'hot_pixel_rate_hz'), gyro_noise=_logu(rng, 'gyro_noise'),
        gyro_bias=_u(rng, 'gyro_bias'), acc_noise=_logu(rng, 'acc_noise'),
        acc_bias=_u(rng, 'acc_bias'))


def _davis_calib(rng: np.random.Generator) -> CameraCalibration:
    fx = _u(rng, 'fx')
    fy = fx * _u(rng, 'fy_ratio')
    cx = 119.5 + _u(rng, 'cx_offset')
    cy = 89.5 + _u(rng, 'cy_offset')
    dist = (0.0, 0.0, 0.0, 0.0, 0.0)
    if rng.random() < 0.5:
        k1 = _u(rng, 'k1')
        dist = (k1, abs(k1) * _u(rng, 'k2_ratio'), _u(rng, 'p12'), _u(rng, 'p12'), 0.0)
    return CameraCalibration(240, 180, fx, fy, cx, cy, dist)


def _texture_params(rng: np.random.Generator, scene: str) -> dict[str, float]:
    if scene in ('shapes', 'sparse'):
        lo = _u(rng, 'size_lo') * (1.5 if scene == 'sparse' else 1.0)
        return {'density': _u(rng, 'sparse_density' if scene == 'sparse' else 'density'),
                'size_lo': lo, 'size_hi': lo * _u(rng, 'size_ratio'), 'light': _u(rng, 'light'),
                'contrast': _u(rng, 'contrast')}
    natural = scene == 'natural'
    return {'slope': _u(rng, 'slope_natural' if natural else 'slope_textured'),
            'contrast': _u(rng, 'texture_contrast'),
            'scale_lo': 0.01 if natural else 0.008, 'scale_hi': 0.5 if natural else 0.06,
            'patches': float(_int(rng, 'patches'))
            if natural else 0.0,
            'patch_contrast': _u(rng, 'patch_contrast') if natural else 0.0}


def _motion_params(rng: np.random.Generator, kind: str
                   ) -> tuple[dict[str, float], tuple[tuple[float, float], ...]]:
    jerky = rng.random() < 0.4
    m = {'style': float(jerky), 'jerk': _u(rng, 'jerk') if jerky else 0.0,
         'env0': _u(rng, 'env0'), 'speed_ratio': _u(rng, 'speed_ratio')}
    if kind == 'rotation':
        m.update(peak=_logu(rng, 'peak_deg_s'), pan=_u(rng, 'pan_tilt_deg'),
                 tilt=_u(rng, 'pan_tilt_deg'), roll=_u(rng, 'roll_deg'), hand=_u(rng, 'hand_m'))
    else:
        m.update(peak=_logu(rng, 'peak_m_s'), x=_u(rng, 'x_m'), y=_u(rng, 'y_m'),
                 z_frac=_u(rng, 'z_frac'), roll=_u(rng, 'trans_roll_deg'),
                 wobble=_u(rng, 'wobble_deg'))
    n_p = _int(rng, 'pauses')
    # pause starts as fractions of the duration (scaled in scene_of), durations in seconds
    pauses = tuple(sorted((float(rng.uniform(0.1, 0.9)), _u(rng, 'pause_s'))
                          for _ in range(n_p)))
    return m, pauses


def draw(kind: str, seed: int) -> Draw:
    """The randomized parameters of sequence ``seed`` of ``kind`` (module docstring).

    Raises:
        ConfigError: for an unknown kind.
    """
    ki = _kind_index(kind)
    rng = np.random.default_rng([seed, 7, ki])
    cfg = _sensor(rng)
    if kind == 'arm':
        hfov = _u(rng, 'arm_hfov_deg')
        f = 320.0 / math.tan(math.radians(hfov / 2))
        k1 = _u(rng, 'arm_k1') if rng.random() < 0.5 else 0.0
        calib = CameraCalibration(640, 480, f, f, 319.5 + 640 * _u(rng, 'arm_centre_frac'),
                                  239.5 + 480 * _u(rng, 'arm_centre_frac'),
                                  (k1, 0.0, 0.0, 0.0, 0.0))
        return Draw(kind, seed, split_of(seed), DEFAULT_SECONDS, 'table', 0.4, calib, cfg,
                    motion={'speed': _u(rng, 'arm_speed')})
    calib = _davis_calib(rng)
    scene = SCENE_KINDS[int(rng.choice(len(SCENE_KINDS), p=_SCENE_P))]
    depth = _u(rng, 'depth_rotation' if kind == 'rotation' else 'depth_translation')
    tex = _texture_params(rng, scene)
    motion, pauses = _motion_params(rng, kind)
    return Draw(kind, seed, split_of(seed), DEFAULT_SECONDS, scene, depth, calib, cfg, tex,
                motion, pauses)


def on_sensor(d: Draw, width: int, height: int | None = None) -> Draw:
    """The draw seen by a sensor ``width`` pixels wide with the same horizontal field of view:
    the calibration scaled by k = width / its width (fx, fy times k, the principal point's
    pixel centres scaled, the same distortion on normalised coordinates); scene, motion,
    contrast thresholds and noise per pixel unchanged, so the event rate grows about as k².
    The height is ``round(k H)`` (the same vertical field of view), or ``height``: rows cut
    from (or added to) top and bottom alike, the principal point moving by half the difference
    (a 16:9 sensor such as 1280x720 or 640x360 sees the middle of the 4:3 view). For a 640x480
    rotation camera: ``on_sensor(draw('rotation', s), 640)``.

    Raises:
        ConfigError: for a width or height below 16 pixels.
    """
    if width < 16 or (height is not None and height < 16):
        raise ConfigError(f'sensor {width}x{height or "auto"} must be at least 16 pixels each '
                          'way')
    c, k = d.calib, width / d.calib.width
    full = round(c.height * k)
    rows = full if height is None else height
    calib = CameraCalibration(width, rows, c.fx * k, c.fy * k, (c.cx + 0.5) * k - 0.5,
                              (c.cy + 0.5) * k - 0.5 - (full - rows) / 2, c.dist)
    return replace(d, calib=calib)


def preset(name: str, seed: int = 0) -> Draw:
    """A fixed configuration like a real recording; only texture, waves and noise vary by seed.

    ``'shapes_rotation'``: 60 s, the real DAVIS240C calibration (fx 199.09, fy 198.83,
    cx 132.19, cy 110.71, k1 -0.368, k2 0.151), a shapes poster 1 m away, smooth hand-held
    rotation whose amplitude ramps from 30 % and speed rises 9x to a peak of 650 deg/s at the
    end, default sensor and IMU noise.

    Raises:
        ConfigError: for an unknown preset.
    """
    if name != 'shapes_rotation':
        raise ConfigError(f'unknown preset {name!r}; use one of {", ".join(PRESETS)}')
    calib = CameraCalibration(240, 180, 199.092366542, 198.82882047, 132.192071378,
                              110.712660011, (-0.368436311798, 0.150947243557, -0.000296130534,
                                              -0.000759431482, 0.0))
    tex = {'density': 6.5, 'size_lo': 0.03, 'size_hi': 0.08, 'light': 0.8, 'contrast': 0.85}
    motion = {'style': 0.0, 'jerk': 0.0, 'env0': 0.3, 'speed_ratio': 9.0, 'peak': 650.0,
              'pan': 20.0, 'tilt': 20.0, 'roll': 50.0, 'hand': 0.004}
    return Draw('rotation', seed, 'preset', 60.0, 'shapes', 1.0, calib, SimulatorConfig(), tex,
                motion)


def _texture(d: Draw, rng: np.random.Generator, half_extent: float, texel: float) -> Texture:
    p, s = d.texture, d.depth_m
    blur = 0.6 * s / d.calib.fx
    if d.scene in ('shapes', 'sparse'):
        light, c = p['light'], p['contrast']
        return shapes_texture(rng, half_extent=half_extent, texel=texel,
                              density=p['density'] / (s * s), blur_m=blur,
                              size=(p['size_lo'] * s, p['size_hi'] * s), light=light,
                              dark=(light * (1 - c), light * (1 - 0.7 * c)),
                              grey=(light * (1 - 0.7 * c), light * (1 - 0.3 * c)))
    return natural_texture(rng, half_extent=half_extent, texel=texel, blur_m=blur,
                           scales_m=(p['scale_lo'] * s, p['scale_hi'] * s), slope=p['slope'],
                           contrast=p['contrast'], patches=int(p['patches']),
                           patch_contrast=p['patch_contrast'])


def scene_of(d: Draw, seconds: float | None = None) -> Scene:
    """The scene (camera, texture, motion) of a draw, for a sequence of ``seconds``.

    Raises:
        ConfigError: for a non-positive duration.
    """
    T = d.seconds if seconds is None else seconds
    if not T > 0:
        raise ConfigError(f'seconds = {T} must be positive')
    rng = np.random.default_rng([d.seed, 8, _kind_index(d.kind)])
    m = d.motion
    if d.kind == 'arm':
        f = d.calib.fx
        texture = table_texture(rng, x_range=(-0.25, 1.15), y_range=(-0.75, 0.75),
                                texel=0.0007, blur_m=0.6 * 0.4 / f)
        return Scene('arm', d.calib, texture, 0.0, ArmMotion(rng, T, m['speed']),
                     (0.0, 0.0, -GRAVITY), render_px_scale=2.0)
    s = d.depth_m
    progress = Progress(T, m['speed_ratio'],
                        tuple((frac * T, dur) for frac, dur in d.pauses))
    texel = 0.0025 * s
    motion: RampedMotion
    if d.kind == 'rotation':
        view = math.radians(min(max(m['pan'], m['tilt']) + 45.0, 76.0))
        half = s * math.tan(view) + m['hand']
        motion = RampedMotion(rng, progress, angle_limits=(m['pan'] * _DEG, m['tilt'] * _DEG,
                                                           m['roll'] * _DEG),
                              offsets=(m['hand'],) * 3, env0=m['env0'], jerk=m['jerk'])
        motion.set_peak(m['peak'], 'deg_s')
    else:
        z = m['z_frac'] * s
        half = max(m['x'], m['y']) + (s + z) * math.tan(math.radians(45.0 + m['wobble']))
        motion = RampedMotion(rng, progress, angle_limits=(m['wobble'] * _DEG,
                                                           m['wobble'] * _DEG, m['roll'] * _DEG),
                              offsets=(m['x'], m['y'], z), env0=m['env0'], jerk=m['jerk'])
        motion.set_peak(m['peak'], 'm_s')
    texture = _texture(d, rng, half, texel)
    return Scene(d.kind, d.calib, texture, s, motion, (0.0, GRAVITY, 0.0))


def simulate_draw(d: Draw, seconds: float | None = None, *,
                  progress: Callable[[float], None] | None = None) -> Sequence:
    """Simulate a draw (events, calibration, IMU, ground truth) for ``seconds``.

    Args:
        d: The draw (:func:`draw` or :func:`preset`).
        seconds: Duration (default ``d.seconds``).
        progress: Called with the simulated seconds completed since the last call.

    Raises:
        ConfigError: for a non-positive duration.
    """
    T = d.seconds if seconds is None else seconds
    return simulate_scene(scene_of(d, T), T, seed=d.seed, config=d.config, progress=progress)
