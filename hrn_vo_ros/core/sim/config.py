"""Simulator constants and the sensor / noise / rendering configuration."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from hrn_vo_ros.core.configbase import param, validate

Kind = Literal['rotation', 'translation', 'arm']
KINDS: tuple[str, ...] = ('rotation', 'translation', 'arm')
GRAVITY = 9.81
PLANE_Z: dict[str, float] = {'rotation': 1.0, 'translation': 0.8, 'arm': 0.0}
LOG_EPS = 0.02   # log intensity L = log(I + LOG_EPS)
#: Each hot pixel fires at ``hot_pixel_rate_hz`` times a factor drawn uniformly from this range
#: (per pixel, once per sequence): 1.15 times the nominal rate on average.
HOT_RATE_RANGE = (0.3, 2.0)


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
    hot_pixel_rate_hz: float = param(150.0, 'nominal event rate of a hot pixel, Hz (each fires '
                                     'at 0.3-2.0 times it, 1.15 times on average)', lo=0.0,
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
    gt_rate_hz: float = param(1000.0, 'ground-truth rate, Hz (motion capture gives 100-200; the '
                              'simulator knows every pose; evo pairs nearest stamps)',
                              lo=1.0, hi=1e5)
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

    @property
    def hot_events_per_s(self) -> float:
        """Expected events per second of all hot pixels together (:data:`HOT_RATE_RANGE`)."""
        return self.hot_pixels * self.hot_pixel_rate_hz * 0.5 * sum(HOT_RATE_RANGE)

    def __post_init__(self) -> None:
        validate(self)

