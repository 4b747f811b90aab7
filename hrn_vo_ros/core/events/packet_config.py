"""The packetizer's configuration: how events become frames (:class:`PacketizerConfig`).

One dataclass is the single source of truth for the defaults, the YAML files and the ROS
parameters of the packetizer (``packetizer_node``, ``hrn-vo run``): the packet size and its
time limits, the event-rate cap (``max_frame_hz``), the downsampling factor (``downsample``;
0, the default: the auto factor that fits any sensor into :data:`VALIDATED_FRAME`), the
per-pixel threshold, rectification with its calibration (:class:`CalibrationConfig`,
:func:`with_calibration`), denoising, the noisy-sensor threshold and the gyro's packets
(:class:`FramingImuConfig`). :func:`paper_framing` is the paper's packetizer. The mechanisms
are :mod:`.frames` (binning), :mod:`.ratecap`, :mod:`.camera` (rectification), :mod:`.denoise`
and :mod:`.noise`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import Any

from hrn_vo_ros.core.configbase import nested, param, validate
from hrn_vo_ros.core.events.camera import RECTIFY_MODES
from hrn_vo_ros.core.events.sequence import CameraCalibration
from hrn_vo_ros.errors import ConfigError, DatasetError


@dataclass(frozen=True, slots=True)
class CalibrationConfig:
    """Intrinsics of the sensor (``calib.txt`` / ``CameraInfo`` plumb-bob), for ``rectify``."""

    fx: float = param(0.0, 'focal length x in sensor pixels (0: unknown, taken from the dataset '
                      "calib.txt or the node's camera_info topic)", lo=0.0, hi=1e6)
    fy: float = param(0.0, 'focal length y in sensor pixels (0: unknown)', lo=0.0, hi=1e6)
    cx: float = param(0.0, 'principal point x in sensor pixels', lo=-1e6, hi=1e6)
    cy: float = param(0.0, 'principal point y in sensor pixels', lo=-1e6, hi=1e6)
    dist: tuple[float, ...] = param((0.0, 0.0, 0.0, 0.0, 0.0),
                                    'distortion k1 k2 p1 p2 k3 (radial-tangential / plumb_bob)',
                                    lo=-1e3, hi=1e3)

    def __post_init__(self) -> None:
        validate(self)
        if len(self.dist) != 5:
            raise ConfigError(f'calib.dist has {len(self.dist)} values; give the 5 plumb-bob '
                              'coefficients k1 k2 p1 p2 k3')
        if (self.fx > 0) != (self.fy > 0):
            raise ConfigError('calib.fx and calib.fy must both be set (> 0) or both be 0')

    @property
    def known(self) -> bool:
        """True when the focal lengths are set."""
        return self.fx > 0


@dataclass(frozen=True, slots=True)
class FramingImuConfig:
    """Packets when the resonator fuses a gyro: the gyro carries the motion between frames, so
    a steady frame rate matters more than the information of each frame (docs/demo.md)."""

    enabled: bool = param(False, 'the resonator fuses a gyro (launch use_imu:=true, hrn-vo '
                          'run --imu): packets close by imu.max_frame_ms')
    max_frame_ms: float = param(100.0, 'with the gyro, a packet also closes once it spans this '
                                'many ms and holds at least min_frame_events events; 0: '
                                'max_frame_ms as without the gyro', lo=0.0, hi=1e6)


#: The frame size the network was validated at (96x72: a DAVIS240C at downsample 2.5);
#: ``downsample: 0`` fits any sensor into it.
VALIDATED_FRAME = (96, 72)


@dataclass(frozen=True, slots=True)
class PacketizerConfig:
    """How events become frames (one packet of ``events_per_frame`` events per frame)."""

    events_per_frame: int = param(2000, 'events per packet (2000 shapes, 5000 robot arm)',
                                  lo=1, hi=10_000_000)
    sensor_width: int = param(240, 'sensor width in pixels (DAVIS240C 240, Prophesee 640)',
                              lo=1, hi=65535, read_only=True)
    sensor_height: int = param(180, 'sensor height in pixels (DAVIS240C 180, Prophesee 480)',
                               lo=1, hi=65535, read_only=True)
    downsample: float = param(0.0, 'coordinate downsampling factor f: x_out = floor((x+0.5)/f) '
                              '(2.5: 240x180 -> 96x72; 10: 640x480 -> 64x48); 0: auto, frames '
                              'of at most 96x72 from any sensor (f = max(sensor_width / 96, '
                              'sensor_height / 72, 1))', lo=0.0, hi=1000.0, read_only=True)
    min_events_per_pixel: int = param(1, 'a frame pixel is 1 with at least this many events '
                                      '(1: ">0", shapes; 2: ">1", robot arm)', lo=1, hi=1000)
    rectify: str = param('none', 'move events to an ideal camera before binning: none, pinhole '
                         '(undistorted), equidistant (undistorted, radius = f * angle); '
                         'needs calib', choices=RECTIFY_MODES, read_only=True)
    denoise_ms: float = param(0.0, 'background-activity filter: keep an event only when one '
                              'of its 8 neighbouring sensor pixels fired in the same or the '
                              'previous bin of this many ms (lone noise events and hot pixels '
                              'go; delays events by up to one bin); 0: off', lo=0.0, hi=1000.0)
    noise_floor_hz: float = param(0.4, 'when the background rate (isolated events per '
                                  'second per sensor pixel in the first full window of the '
                                  'stream, noise_window_ms) is at least this and their share '
                                  'at least noise_share, every frame pixel needs one event '
                                  'more than min_events_per_pixel (a noisy sensor); no frame '
                                  'comes out before it is measured; 0: off', lo=0.0, hi=1e6)
    noise_share: float = param(0.0, 'fewest isolated events per event of that window for the '
                               'noisy-sensor threshold (a textured scene in motion also makes '
                               'isolated events, but among many others)', lo=0.0, hi=1.0)
    noise_window_ms: float = param(250.0, 'window of the background-rate measurement, ms',
                                   lo=1.0, hi=1e6)
    noise_isolation_ms: float = param(5.0, 'an event is isolated without another event in its '
                                      '3x3 pixels within the same or an adjacent bin of this '
                                      'many ms', lo=0.001, hi=1e6)
    max_frame_ms: float = param(100.0, 'a packet also closes once it spans this many ms and '
                                'holds at least min_frame_events events (slow or sparse '
                                'scenes still give frames at a steady rate); 0: off, every '
                                'packet holds events_per_frame events', lo=0.0, hi=1e6)
    max_frame_hz: float = param(1500.0, 'event-rate cap: above events_per_frame x '
                                'max_frame_hz events per second (the count of the previous '
                                'rate_window_ms) only an even share of the events is binned, '
                                'so that a high-resolution sensor in fast motion gives about '
                                'as many frames per second as the validated 240x180 sensor '
                                '(one core runs 600-1000 frames/s: lower it for real time on '
                                'such a sensor); 0: off', lo=0.0, hi=1e7)
    rate_window_ms: float = param(10.0, 'window of the event-rate cap, ms', lo=1.0, hi=1e6)
    min_frame_events: int = param(250, 'fewest events of a packet closed by max_frame_ms (a '
                                  'still camera waits for them; at most events_per_frame)',
                                  lo=1, hi=10_000_000)
    refill: bool = param(True, 'a packet closed by max_frame_ms is binned together with '
                         'the events before it, up to events_per_frame: every frame holds the '
                         'newest events_per_frame events (consecutive frames then overlap), so '
                         'a slow scene gets frames at a steady rate that are as full as a '
                         'whole packet; not under the limit of the gyro (imu.max_frame_ms), '
                         'where the gyro carries the motion between thin frames; false: such a '
                         'packet is binned alone')
    calib: CalibrationConfig = nested(CalibrationConfig, 'sensor intrinsics for rectify')
    imu: FramingImuConfig = nested(FramingImuConfig, 'packets with a fused gyro')

    def __post_init__(self) -> None:
        validate(self)
        if not (math.isfinite(self.downsample)
                and (self.downsample == 0.0 or self.downsample >= 1.0)):
            raise ConfigError(f'PacketizerConfig.downsample = {self.downsample}: set a factor '
                              '>= 1, or 0 for frames of about 96x72 from any sensor')

    @property
    def gyro_limit(self) -> bool:
        """Whether the gyro's own packet time limit is in force (``imu.enabled`` and
        ``imu.max_frame_ms`` set): it replaces ``max_frame_ms`` and its packets are not
        refilled."""
        return self.imu.enabled and self.imu.max_frame_ms > 0

    @property
    def frame_ms(self) -> float:
        """The packet time limit in force: ``imu.max_frame_ms`` under :attr:`gyro_limit`, else
        ``max_frame_ms`` (0: packets close by count only)."""
        return self.imu.max_frame_ms if self.gyro_limit else self.max_frame_ms

    @property
    def max_frame_ns(self) -> int:
        """:attr:`frame_ms` in int64 nanoseconds (0: packets close by count only)."""
        return round(self.frame_ms * 1e6)

    @property
    def min_events(self) -> int:
        """The fewest events of a packet closed by time: ``min_frame_events``, at most
        ``events_per_frame`` (with fewer events per frame every packet closes by count)."""
        return min(self.min_frame_events, self.events_per_frame)

    @property
    def refills(self) -> bool:
        """Whether packets closed by time are refilled (``refill``, with ``max_frame_ms`` in
        force: not when the gyro's ``imu.max_frame_ms`` replaces it)."""
        return self.refill and self.max_frame_ms > 0 and not self.gyro_limit

    @property
    def max_per_window(self) -> float:
        """Events a window of ``rate_window_ms`` keeps at most (0: no cap)."""
        return self.max_frame_hz * self.events_per_frame * self.rate_window_ms * 1e-3

    @property
    def factor(self) -> float:
        """The downsampling factor in force: ``downsample``, or for 0 (auto) the smallest that
        fits the sensor into :data:`VALIDATED_FRAME` (at least 1)."""
        if self.downsample > 0.0:
            return self.downsample
        w, h = VALIDATED_FRAME
        return max(self.sensor_width / w, self.sensor_height / h, 1.0)

    @property
    def width(self) -> int:
        """Frame width in pixels, ceil(sensor_width / factor)."""
        return out_size(self.sensor_width, self.factor)

    @property
    def height(self) -> int:
        """Frame height in pixels, ceil(sensor_height / factor)."""
        return out_size(self.sensor_height, self.factor)


def paper_framing(**overrides: Any) -> PacketizerConfig:
    """The paper's packetizer (plain binning: packets of ``events_per_frame`` events, no
    noise-floor threshold, no time limit, no event-rate cap, downsample 2.5), the defaults of
    the first rounds, with ``overrides`` (field values) on top; the defaults add the noise
    floor, the rate cap, the refilled 100 ms time limit and the auto downsample of the
    validated network
    (``hrn_vo_ros.core.hrn.config.PAPER_NETWORK`` is the resonator's counterpart)."""
    imu = overrides.pop('imu', FramingImuConfig(max_frame_ms=0.0))
    fields = {'noise_floor_hz': 0.0, 'min_frame_events': 500, 'downsample': 2.5,
              'max_frame_hz': 0.0, 'max_frame_ms': 0.0, 'refill': False, **overrides}
    return PacketizerConfig(imu=imu, **fields)


def out_size(n: int, f: float) -> int:
    """Frames of a sensor of n pixels at factor f: ceil(n / f), at least 1."""
    # Tolerate float noise (240 / 2.5 = 96.00000000000001 must give 96).
    return max(1, math.ceil(n / f - 1e-9))


def with_calibration(cfg: PacketizerConfig, calib: CameraCalibration) -> PacketizerConfig:
    """``cfg`` with ``calib`` filled in from a dataset's calibration when it is still unknown.

    Explicit ``calib.*`` values win; without rectification the config is returned unchanged.

    Raises:
        DatasetError: if the calibration is for another sensor size.
    """
    if cfg.rectify == 'none' or cfg.calib.known:
        return cfg
    if (calib.width, calib.height) != (cfg.sensor_width, cfg.sensor_height):
        raise DatasetError(f'the calibration is for a {calib.width}x{calib.height} sensor, the '
                           f'events for {cfg.sensor_width}x{cfg.sensor_height}')
    return replace(cfg, calib=CalibrationConfig(fx=calib.fx, fy=calib.fy, cx=calib.cx,
                                                cy=calib.cy, dist=tuple(calib.dist)))
