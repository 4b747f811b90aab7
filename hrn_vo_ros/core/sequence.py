"""Plain data types shared by the simulator, the dataset readers, the estimator and evaluation.

All times are int64 nanoseconds on the sensor clock (see :mod:`hrn_vo_ros.core.events`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events import EventArray
from hrn_vo_ros.errors import DatasetError


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
