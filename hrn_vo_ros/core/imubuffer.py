"""A bounded gyro buffer for streaming use: the integrated gyro between frame times, on arrival.

Batch processing integrates the whole IMU record with
:class:`~hrn_vo_ros.core.imu.GyroIntegrator`. A node receives the samples one by one, so it
keeps a short window and asks for the rotation between the previous and the current frame time
once a sample at or after the current frame time has arrived (:meth:`GyroBuffer.covers`). The
window always holds the last sample at or before the previous frame time, so the interpolation
and trapezoid integration see the same samples as the batch integrator and give the same
increment (up to float rounding of the time origin).
"""

from __future__ import annotations

from collections import deque
import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.imu import GyroIntegrator
from hrn_vo_ros.core.sequence import ImuData
from hrn_vo_ros.errors import DatasetError


class GyroBuffer:
    """Recent gyro samples and the rotation between two frame times.

    Args:
        camera_from_imu: Rotation from IMU axes to camera axes (3x3).
        max_samples: Bound on the buffer (oldest samples are dropped beyond it).
    """

    def __init__(self, camera_from_imu: NDArray[np.float64] | None = None, *,
                 max_samples: int = 20000) -> None:
        self._rot = None if camera_from_imu is None else np.asarray(camera_from_imu, float)
        self._t: deque[int] = deque(maxlen=max_samples)
        self._g: deque[NDArray[np.float64]] = deque(maxlen=max_samples)
        self.ended = False

    def __len__(self) -> int:
        return len(self._t)

    @property
    def newest_ns(self) -> int | None:
        """Time of the newest sample, or None when empty."""
        return self._t[-1] if self._t else None

    def add(self, t_ns: int, gyro: NDArray[np.float64]) -> None:
        """Append one sample (rad/s, IMU axes).

        Raises:
            DatasetError: if the rate is not finite or the time does not increase.
        """
        g = np.asarray(gyro, dtype=np.float64).reshape(3)
        if not all(math.isfinite(float(v)) for v in g):
            raise DatasetError(f'gyro sample {g.tolist()} at {t_ns} ns is not finite')
        if self._t and t_ns <= self._t[-1]:
            raise DatasetError(f'IMU time {t_ns} ns does not increase (previous '
                               f'{self._t[-1]} ns)')
        self._t.append(int(t_ns))
        self._g.append(g)

    def covers(self, t_ns: int) -> bool:
        """Whether a sample at or after ``t_ns`` has arrived (the increment to it is final)."""
        return bool(self._t) and self._t[-1] >= t_ns

    def delta(self, t_prev_ns: int, t_ns: int) -> NDArray[np.float64]:
        """Integrated gyro from ``t_prev_ns`` to ``t_ns`` (rad, camera axes).

        Times outside the buffered span are clamped to it, as the batch integrator does at the
        ends of a record. Fewer than 2 samples give a zero rotation.

        Shapes:
            returns (3,).
        """
        if len(self._t) < 2:
            return np.zeros(3)
        t = np.fromiter(self._t, np.int64, len(self._t))
        i0 = max(int(np.searchsorted(t, t_prev_ns, side='right')) - 1, 0)
        i1 = min(int(np.searchsorted(t, t_ns, side='left')) + 1, len(t))
        i0 = min(i0, len(t) - 2)
        i1 = min(max(i1, i0 + 2), len(t))
        g = np.array(list(self._g)[i0:i1])
        integ = GyroIntegrator(ImuData(t[i0:i1], np.zeros_like(g), g), self._rot)
        a = integ.angle_at(np.array([t_prev_ns, t_ns], np.int64))
        return np.asarray(a[1] - a[0], dtype=np.float64)

    def trim(self, t_prev_ns: int) -> None:
        """Drop samples no longer needed once ``t_prev_ns`` is the previous frame time."""
        while len(self._t) > 2 and self._t[1] <= t_prev_ns:
            self._t.popleft()
            self._g.popleft()
