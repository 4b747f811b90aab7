"""Plain data types shared by the simulator, the dataset readers, the estimator and evaluation.

All times are int64 nanoseconds on the sensor clock (see :mod:`hrn_vo_ros.core.events.arrays`).
"""

from __future__ import annotations

from collections.abc import Sequence as Seq
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import ConfigError, DatasetError, DecodeError


@dataclass(frozen=True, slots=True)
class CameraCalibration:
    """Pinhole intrinsics and radial-tangential distortion of the event camera.

    The Event Camera Dataset's ``calib.txt`` holds ``fx fy cx cy k1 k2 p1 p2 k3`` on one line.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    dist: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise DatasetError(f'sensor size {self.width}x{self.height} must be positive')
        if not (self.fx > 0 and self.fy > 0):
            raise DatasetError(f'focal lengths fx={self.fx}, fy={self.fy} must be positive')


#: A camera's focal length fx (sensor pixels) and its sensor size (width, height), from its
#: camera_info (``core.live.camera_focal_px`` scales it to frame pixels).
CameraFocal = tuple[float, tuple[int, int]]


def camera_focal(fx: float, width: int, height: int, *,
                 remedy: str = 'set focal_px') -> CameraFocal:
    """A camera's focal length (sensor pixels) and sensor size, checked: a CameraInfo's
    ``k[0]``, ``width`` and ``height`` (``remedy``: what the error tells to set instead).

    Raises:
        DecodeError: for an uncalibrated camera (fx not a positive number) or a bad size.
    """
    if width <= 0 or height <= 0:
        raise DecodeError(f'camera_info size {width}x{height} is not a sensor size')
    if not (math.isfinite(fx) and fx > 0.0):
        raise DecodeError(f'camera_info has no focal length (k[0] = {fx:g}: the camera is not '
                          f'calibrated); calibrate it or {remedy}')
    return fx, (width, height)


#: CameraInfo distortion models read as plumb-bob (``k1 k2 p1 p2 k3``).
PLUMB_BOB_MODELS = ('plumb_bob', 'radtan', 'rational_polynomial')


def calibration_from_camera_info(width: int, height: int, k: Seq[float], d: Seq[float],
                                 model: str) -> CameraCalibration:
    """The calibration a ``sensor_msgs/CameraInfo`` holds (its width, height, K, D and
    distortion model).

    ``plumb_bob`` (``k1 k2 p1 p2 k3``) is read as is; ``rational_polynomial`` only when its extra
    coefficients are 0 (then it is plumb-bob); an empty model with no coefficients is a pinhole.

    Raises:
        DecodeError: for an uncalibrated camera (zero focal length), an unsupported model or a
            bad size.
    """
    k, d = [float(v) for v in k], [float(v) for v in d]
    remedy = 'set the calib.* parameters'
    camera_focal(k[0], width, height, remedy=remedy)
    if not (math.isfinite(k[4]) and k[4] > 0.0):
        raise DecodeError(f'camera_info has no focal length fy (k[4] = {k[4]:g}: the camera is '
                          f'not calibrated); calibrate it or {remedy}')
    if model not in PLUMB_BOB_MODELS and not (model == '' and not any(d)):
        raise DecodeError(f'camera_info distortion model {model!r} is not supported; use '
                          'plumb_bob (k1 k2 p1 p2 k3)')
    if any(d[5:]):
        raise DecodeError(f'camera_info has {len(d)} distortion coefficients, the ones past k3 '
                          'non-zero; only plumb_bob (5) is supported')
    d5 = (d + [0.0] * 5)[:5]
    return CameraCalibration(width=width, height=height, fx=k[0], fy=k[4], cx=k[2], cy=k[5],
                             dist=(d5[0], d5[1], d5[2], d5[3], d5[4]))


@dataclass(frozen=True, slots=True, eq=False)
class ImuData:
    """IMU samples in the sensor (camera IMU) frame.

    Shapes:
        t: (n,) int64 ns; acc: (n, 3) m/s^2; gyro: (n, 3) rad/s (x, y, z axes of the IMU frame).
    """

    t: NDArray[np.int64]
    acc: NDArray[np.float64]
    gyro: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True, slots=True, eq=False)
class Trajectory:
    """Poses of the camera in a world frame (ground truth or estimates), time-ordered.

    ``pos[i]`` is the camera position in the world and ``quat[i]`` (x, y, z, w) its orientation
    (camera-to-world rotation), as in the Event Camera Dataset's ``groundtruth.txt``.

    Shapes:
        t: (n,) int64 ns; pos: (n, 3) metres; quat: (n, 4) unit quaternions x, y, z, w.
    """

    t: NDArray[np.int64]
    pos: NDArray[np.float64]
    quat: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True, slots=True, eq=False)
class Sequence:
    """A whole recording held in memory (simulated sequences, small fixtures)."""

    events: EventArray
    calib: CameraCalibration
    imu: ImuData | None = None
    groundtruth: Trajectory | None = None


def random_sequence(rng: np.random.Generator, seconds: float, rate: float, *,
                    stamps: str = 'ns', imu_period_ns: int = 1_000_000,
                    gt_every: int = 5) -> Sequence:
    """A DAVIS240-sized sequence of random content, for I/O tests and benchmarks (not physics:
    :mod:`hrn_vo_ros.core.sim.simulator` renders a scene).

    Events uniformly at random in time, position and polarity; IMU and ground truth random on a
    regular clock (identity orientations).

    Args:
        rng: The random source.
        seconds: Duration.
        rate: Events per second.
        stamps: ``'ns'`` (any nanosecond), ``'us'`` (whole microseconds, as the text layout
            stores them) or ``'mixed'`` (most on whole microseconds, some 999 ns past).
        imu_period_ns: IMU sample period.
        gt_every: A ground-truth pose every this many IMU samples.

    Raises:
        ConfigError: for an unknown ``stamps``.
    """
    n = int(seconds * rate)
    t = np.sort(rng.integers(0, int(seconds * 1e9), n))
    if stamps == 'us':
        t = t // 1000 * 1000
    elif stamps == 'mixed':
        t = np.sort(t - t % 1000 + 999 * (t % 7 == 0))
    elif stamps != 'ns':
        raise ConfigError(f"stamps must be 'ns', 'us' or 'mixed', not {stamps!r}")
    ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                rng.integers(0, 2, n))
    ti = np.arange(0, int(seconds * 1e9), imu_period_ns, dtype=np.int64)
    imu = ImuData(t=ti, acc=rng.normal(size=(ti.size, 3)), gyro=rng.normal(size=(ti.size, 3)))
    tg = ti[::gt_every]
    gt = Trajectory(t=tg, pos=rng.normal(size=(tg.size, 3)),
                    quat=np.tile([0.0, 0.0, 0.0, 1.0], (tg.size, 1)))
    calib = CameraCalibration(width=240, height=180, fx=199.0, fy=198.0, cx=120.0, cy=90.0)
    return Sequence(events=ev, calib=calib, imu=imu, groundtruth=gt)
