"""Gyro integration between frame times for the HRN's IMU prediction step (hrn_math.md §6).

The gyro is linearly interpolated at the frame times and integrated with the trapezoid rule over
all samples in between, giving the rotation vector (small-angle) of the camera between two frames.
Axes: the result is in the **camera** frame (x right, y down, z forward) after applying
``camera_from_imu`` (a 3x3 rotation, identity when the IMU axes are the camera axes).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.sequence import ImuData
from hrn_vo_ros.errors import DatasetError


class GyroIntegrator:
    """Integrated gyro between consecutive frame times.

    Args:
        imu: IMU samples (time-ordered, gyro in rad/s).
        camera_from_imu: Rotation from IMU axes to camera axes (row-major 3x3), default identity.

    Raises:
        DatasetError: if there are fewer than 2 samples or the times are not increasing.
    """

    def __init__(self, imu: ImuData, camera_from_imu: NDArray[np.float64] | None = None) -> None:
        if len(imu) < 2:
            raise DatasetError('the IMU data need at least 2 samples for gyro integration')
        t = np.asarray(imu.t, dtype=np.int64)
        if np.any(np.diff(t) <= 0):
            raise DatasetError('IMU time stamps must be strictly increasing')
        rot = np.eye(3) if camera_from_imu is None else np.asarray(camera_from_imu, float)
        if rot.shape != (3, 3):
            raise DatasetError(f'camera_from_imu must be 3x3, got shape {rot.shape}')
        self._t = (t - t[0]).astype(np.float64) * 1e-9
        self._t0 = int(t[0])
        self._g = np.asarray(imu.gyro, dtype=np.float64) @ rot.T
        # Cumulative trapezoid integral of the gyro at the sample times.
        inc = 0.5 * (self._g[1:] + self._g[:-1]) * np.diff(self._t)[:, None]
        self._cum = np.vstack([np.zeros((1, 3)), np.cumsum(inc, axis=0)])

    def angle_at(self, t_ns: NDArray[np.int64] | int) -> NDArray[np.float64]:
        """Integrated gyro (rad, camera axes) from the first IMU sample to ``t_ns``.

        Times outside the IMU span are clamped to it.

        Shapes:
            t_ns: (n,) or scalar; returns (n, 3) or (3,).
        """
        tq = (np.atleast_1d(np.asarray(t_ns, dtype=np.int64)) - self._t0) * 1e-9
        tq = np.clip(tq, self._t[0], self._t[-1])
        i = np.clip(np.searchsorted(self._t, tq, side='right') - 1, 0, len(self._t) - 2)
        dt = (tq - self._t[i])[:, None]
        span = (self._t[i + 1] - self._t[i])[:, None]
        g0, g1 = self._g[i], self._g[i + 1]
        gq = g0 + (g1 - g0) * (dt / span)
        out = self._cum[i] + 0.5 * (g0 + gq) * dt
        res = out[0] if np.ndim(t_ns) == 0 else out
        return np.asarray(res, np.float64)

    def deltas(self, t_ns: NDArray[np.int64]) -> NDArray[np.float64]:
        """Rotation between consecutive frame times (first row 0).

        Shapes:
            t_ns: (n,); returns (n, 3) rad.
        """
        a = self.angle_at(np.asarray(t_ns, dtype=np.int64))
        return np.vstack([np.zeros((1, 3)), np.diff(a, axis=0)])
