"""A bounded gyro buffer for streaming use: the batch integrator's numbers, sample by sample.

Batch processing integrates the whole IMU record with
:class:`~hrn_vo_ros.core.odometry.imu.GyroIntegrator` (trapezoid rule from the first sample, linear
interpolation at frame times). A node receives the samples one by one, so it keeps a short
window, but the same state as the batch integrator: times as float seconds since the **first**
sample and the running cumulative integral, accumulated in the same order with the same
expressions. :meth:`GyroBuffer.angle_at` therefore returns bit-identical values to
``GyroIntegrator.angle_at`` (for the identity ``camera_from_imu``; another rotation may differ in
the last bit through the matrix product), so a node reproduces ``hrn-vo run --imu`` exactly. A
frame's angle is final once a sample at or after its time arrived (:meth:`GyroBuffer.covers`).
"""

from __future__ import annotations

from collections import deque
import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.errors import DatasetError


class GyroBuffer:
    """Recent gyro samples with the integral since the first sample.

    Args:
        camera_from_imu: Rotation from IMU axes to camera axes (3x3), default identity.
        max_samples: Bound on the buffer (oldest samples are dropped beyond it).
    """

    def __init__(self, camera_from_imu: NDArray[np.float64] | None = None, *,
                 max_samples: int = 20000) -> None:
        self._rot = np.eye(3) if camera_from_imu is None else np.asarray(camera_from_imu, float)
        self._t0: int | None = None
        self._ns: deque[int] = deque(maxlen=max_samples)
        self._s: deque[float] = deque(maxlen=max_samples)       # seconds since the first sample
        self._g: deque[NDArray[np.float64]] = deque(maxlen=max_samples)  # camera axes
        self._cum: deque[NDArray[np.float64]] = deque(maxlen=max_samples)
        self._last_angle: NDArray[np.float64] | None = None     # of the last increment()

    def __len__(self) -> int:
        return len(self._ns)

    def add(self, t_ns: int, gyro: NDArray[np.float64]) -> None:
        """Append one sample (rad/s, IMU axes).

        Raises:
            DatasetError: if the rate is not finite or the time does not increase.
        """
        g_imu = np.asarray(gyro, dtype=np.float64).reshape(1, 3)
        if not all(math.isfinite(float(v)) for v in g_imu[0]):
            raise DatasetError(f'gyro sample {g_imu[0].tolist()} at {t_ns} ns is not finite')
        if self._ns and t_ns <= self._ns[-1]:
            raise DatasetError(f'IMU time {t_ns} ns does not increase (previous '
                               f'{self._ns[-1]} ns)')
        if self._t0 is None:
            self._t0 = int(t_ns)
        s = float((np.int64(t_ns) - np.int64(self._t0)).astype(np.float64) * 1e-9)
        g = (g_imu @ self._rot.T)[0]
        if self._ns:   # the batch integrator's inc = 0.5 * (g[k+1] + g[k]) * diff(t), cumsum
            inc = 0.5 * (g + self._g[-1]) * (s - self._s[-1])
            cum = self._cum[-1] + inc
        else:
            cum = np.zeros(3)
        self._ns.append(int(t_ns))
        self._s.append(s)
        self._g.append(g)
        self._cum.append(cum)

    def covers(self, t_ns: int) -> bool:
        """Whether a sample at or after ``t_ns`` has arrived (the angle at it is final)."""
        return bool(self._ns) and self._ns[-1] >= t_ns

    def angle_at(self, t_ns: int) -> NDArray[np.float64]:
        """Integrated gyro (rad, camera axes) from the first sample to ``t_ns``.

        Times before the first or after the newest sample are clamped, as the batch integrator
        clamps at the ends of a record. Fewer than 2 samples give zeros.

        Shapes:
            returns (3,).
        """
        if len(self._ns) < 2 or self._t0 is None:
            return np.zeros(3)
        ts = np.fromiter(self._s, np.float64, len(self._s))
        tq = (np.atleast_1d(np.asarray(t_ns, dtype=np.int64)) - self._t0) * 1e-9
        tq = np.clip(tq, ts[0], ts[-1])
        i = int(np.clip(np.searchsorted(ts, tq, side='right') - 1, 0, len(ts) - 2)[0])
        dt = (tq - ts[i])[:, None]
        span = (ts[i + 1] - ts[i])
        g0, g1 = self._g[i][None, :], self._g[i + 1][None, :]
        gq = g0 + (g1 - g0) * (dt / span)
        out = self._cum[i][None, :] + 0.5 * (g0 + gq) * dt
        return np.asarray(out[0], np.float64)

    def delta(self, t_prev_ns: int, t_ns: int) -> NDArray[np.float64]:
        """Integrated gyro from ``t_prev_ns`` to ``t_ns`` (rad, camera axes).

        Shapes:
            returns (3,).
        """
        return self.angle_at(t_ns) - self.angle_at(t_prev_ns)

    def increment(self, t_ns: int) -> NDArray[np.float64] | None:
        """Integrated gyro since the previous call (None on the first), as ``hrn-vo run``
        takes it: differences of :meth:`angle_at`, so they survive :meth:`trim`.

        Shapes:
            returns (3,) or None.
        """
        angle = self.angle_at(t_ns)
        prev, self._last_angle = self._last_angle, angle
        return None if prev is None else angle - prev

    def trim(self, t_ns: int) -> None:
        """Drop samples no longer needed when no angle before ``t_ns`` will be asked for."""
        while len(self._ns) > 2 and self._ns[1] <= t_ns:
            for d in (self._ns, self._s, self._g, self._cum):
                d.popleft()
