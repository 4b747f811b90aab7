"""Gyro integration between frame times for the HRN's IMU prediction step.

One integrator serves a whole IMU log (``hrn-vo run --imu``) and a stream of samples (the
resonator node): :class:`GyroIntegrator`. The gyro is linearly interpolated at the frame times
and integrated with the trapezoid rule over all samples in between, giving the rotation vector
(small-angle) of the camera between two frames, which is the prediction the HRN binds its
states with before each frame. Axes: the result is in the **camera** frame (x right, y down, z
forward) after applying ``camera_from_imu`` (a 3x3 rotation, identity when the IMU axes are the
camera axes).

State: the sample times as float seconds since the **first** sample, the rates in camera axes
and the running cumulative integral at every sample. A log is appended at once
(:meth:`GyroIntegrator.extend`, or :meth:`GyroIntegrator.from_imu`), a stream sample by sample
(:meth:`GyroIntegrator.add`); both accumulate in the same order with the same expressions, so
they give bit-identical angles (for a ``camera_from_imu`` of 0/±1 entries such as the identity;
another rotation may differ in the last bit through the matrix product of a row versus a block).
Both uses take a frame's prediction with the same call, :meth:`GyroIntegrator.increment`
(differences of :meth:`GyroIntegrator.angle_at` between consecutive calls). A streaming user
keeps the window short with :meth:`GyroIntegrator.trim` and ``max_samples``; a frame's angle is
final once a sample at or after its time arrived (:meth:`GyroIntegrator.covers`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.sequence import ImuData
from hrn_vo_ros.errors import DatasetError

F64 = NDArray[np.float64]


class GyroIntegrator:
    """Gyro samples with the integral since the first sample, for logs and streams.

    Args:
        camera_from_imu: Rotation from IMU axes to camera axes (row-major 3x3), default identity.
        max_samples: Bound on the samples kept (the oldest are dropped beyond it); None keeps
            all (a log).

    Raises:
        DatasetError: if ``camera_from_imu`` is not 3x3.
    """

    def __init__(self, camera_from_imu: NDArray[np.float64] | None = None, *,
                 max_samples: int | None = None) -> None:
        rot = np.eye(3) if camera_from_imu is None else np.asarray(camera_from_imu, float)
        if rot.shape != (3, 3):
            raise DatasetError(f'camera_from_imu must be 3x3, got shape {rot.shape}')
        self._rot = rot
        self._max = max_samples
        self._t0: int | None = None
        self._ns = np.zeros(0, np.int64)          # sample times (ns)
        self._t = np.zeros(0, np.float64)         # seconds since the first sample
        self._g = np.zeros((0, 3), np.float64)    # rates, camera axes
        self._cum = np.zeros((0, 3), np.float64)  # integral since the first sample
        self._lo = self._n = 0                    # live samples: [_lo, _n)
        self._last_angle: F64 | None = None       # of the last increment()

    @classmethod
    def from_imu(cls, imu: ImuData,
                 camera_from_imu: NDArray[np.float64] | None = None) -> GyroIntegrator:
        """The integrator of a whole IMU log (time-ordered, gyro in rad/s).

        Raises:
            DatasetError: if there are fewer than 2 samples, the times are not increasing or
                ``camera_from_imu`` is not 3x3.
        """
        if len(imu) < 2:
            raise DatasetError('the IMU data need at least 2 samples for gyro integration')
        out = cls(camera_from_imu)
        out.extend(np.asarray(imu.t, dtype=np.int64), np.asarray(imu.gyro, dtype=np.float64))
        return out

    def __len__(self) -> int:
        return self._n - self._lo

    def extend(self, t_ns: NDArray[np.int64], gyro: NDArray[np.float64]) -> None:
        """Append samples (times strictly increasing, rates in rad/s, IMU axes).

        Shapes:
            t_ns: (n,); gyro: (n, 3).

        Raises:
            DatasetError: if the times do not increase (within the batch or after the
                previous sample).
        """
        t = np.asarray(t_ns, dtype=np.int64).reshape(-1)
        if len(t) == 0:
            return
        if np.any(np.diff(t) <= 0):
            raise DatasetError('IMU time stamps must be strictly increasing')
        if self._n and t[0] <= self._ns[self._n - 1]:
            raise DatasetError(f'IMU time {int(t[0])} ns does not increase (previous '
                               f'{int(self._ns[self._n - 1])} ns)')
        if self._t0 is None:
            self._t0 = int(t[0])
        s = (t - self._t0).astype(np.float64) * 1e-9
        g = np.asarray(gyro, dtype=np.float64).reshape(-1, 3) @ self._rot.T
        if self._n:   # continue the running sum: the same additions, in the same order
            k = self._n - 1
            tt = np.concatenate([self._t[k:k + 1], s])
            gg = np.concatenate([self._g[k:k + 1], g])
            inc = 0.5 * (gg[1:] + gg[:-1]) * np.diff(tt)[:, None]
            cum = np.cumsum(np.vstack([self._cum[k:k + 1], inc]), axis=0)[1:]
        else:         # cumulative trapezoid integral at the sample times
            inc = 0.5 * (g[1:] + g[:-1]) * np.diff(s)[:, None]
            cum = np.vstack([np.zeros((1, 3)), np.cumsum(inc, axis=0)])
        self._append(t, s, g, cum)

    def add(self, t_ns: int, gyro: NDArray[np.float64]) -> None:
        """Append one sample (rad/s, IMU axes), as a stream delivers them.

        Raises:
            DatasetError: if the rate is not finite or the time does not increase.
        """
        g_imu = np.asarray(gyro, dtype=np.float64).reshape(1, 3)
        if not all(math.isfinite(float(v)) for v in g_imu[0]):
            raise DatasetError(f'gyro sample {g_imu[0].tolist()} at {t_ns} ns is not finite')
        if self._n and t_ns <= self._ns[self._n - 1]:
            raise DatasetError(f'IMU time {t_ns} ns does not increase (previous '
                               f'{int(self._ns[self._n - 1])} ns)')
        if self._t0 is None:
            self._t0 = int(t_ns)
        s = float((np.int64(t_ns) - np.int64(self._t0)).astype(np.float64) * 1e-9)
        g = (g_imu @ self._rot.T)[0]
        if self._n:   # as extend(): inc = 0.5 * (g[k+1] + g[k]) * diff(t), running sum
            k = self._n - 1
            cum = self._cum[k] + 0.5 * (g + self._g[k]) * (s - self._t[k])
        else:
            cum = np.zeros(3)
        self._append(np.array([t_ns], np.int64), np.array([s]), g[None, :], cum[None, :])

    def _append(self, ns: NDArray[np.int64], s: F64, g: F64, cum: F64) -> None:
        """Store new rows (growing the arrays geometrically), then apply ``max_samples``."""
        n_new = len(ns)
        if self._n + n_new > len(self._ns):
            live = slice(self._lo, self._n)
            cap = max(2 * (self._n - self._lo + n_new), 64)
            arrays = []
            for a in (self._ns, self._t, self._g, self._cum):
                b = np.zeros((cap, *a.shape[1:]), a.dtype)
                b[:self._n - self._lo] = a[live]
                arrays.append(b)
            self._ns, self._t, self._g, self._cum = arrays
            self._n -= self._lo
            self._lo = 0
        end = self._n + n_new
        self._ns[self._n:end], self._t[self._n:end] = ns, s
        self._g[self._n:end], self._cum[self._n:end] = g, cum
        self._n = end
        if self._max is not None and len(self) > self._max:
            self._lo = self._n - self._max

    def covers(self, t_ns: int) -> bool:
        """Whether a sample at or after ``t_ns`` has arrived (the angle at it is final)."""
        return self._n > 0 and int(self._ns[self._n - 1]) >= t_ns

    def angle_at(self, t_ns: NDArray[np.int64] | int) -> F64:
        """Integrated gyro (rad, camera axes) from the first sample to ``t_ns``.

        Times before the oldest or after the newest kept sample are clamped to them (the ends
        of a log). Fewer than 2 samples give zeros.

        Shapes:
            t_ns: (n,) or scalar; returns (n, 3) or (3,).
        """
        if len(self) < 2 or self._t0 is None:
            return np.zeros((3,) if np.ndim(t_ns) == 0 else (np.size(t_ns), 3))
        ts = self._t[self._lo:self._n]
        tq = (np.atleast_1d(np.asarray(t_ns, dtype=np.int64)) - self._t0) * 1e-9
        tq = np.clip(tq, ts[0], ts[-1])
        i = np.clip(np.searchsorted(ts, tq, side='right') - 1, 0, len(ts) - 2)
        dt = (tq - ts[i])[:, None]
        span = (ts[i + 1] - ts[i])[:, None]
        g = self._g[self._lo:self._n]
        g0, g1 = g[i], g[i + 1]
        gq = g0 + (g1 - g0) * (dt / span)
        out = self._cum[self._lo:self._n][i] + 0.5 * (g0 + gq) * dt
        res = out[0] if np.ndim(t_ns) == 0 else out
        return np.asarray(res, np.float64)

    def delta(self, t_prev_ns: int, t_ns: int) -> F64:
        """Integrated gyro from ``t_prev_ns`` to ``t_ns`` (rad, camera axes).

        Shapes:
            returns (3,).
        """
        return self.angle_at(t_ns) - self.angle_at(t_prev_ns)

    def deltas(self, t_ns: NDArray[np.int64]) -> F64:
        """Rotation between consecutive frame times (first row 0).

        Shapes:
            t_ns: (n,); returns (n, 3) rad.
        """
        a = self.angle_at(np.asarray(t_ns, dtype=np.int64))
        return np.vstack([np.zeros((1, 3)), np.diff(a, axis=0)])

    def increment(self, t_ns: int) -> F64 | None:
        """Integrated gyro since the previous call (None on the first): the prediction of the
        frame at ``t_ns``. Differences of :meth:`angle_at`, so they survive :meth:`trim`.

        Shapes:
            returns (3,) or None.
        """
        angle = self.angle_at(t_ns)
        prev, self._last_angle = self._last_angle, angle
        return None if prev is None else angle - prev

    def trim(self, t_ns: int) -> None:
        """Drop samples no longer needed when no angle before ``t_ns`` will be asked for."""
        if len(self) <= 2:
            return
        drop = int(np.searchsorted(self._ns[self._lo + 1:self._n], t_ns, side='right'))
        self._lo += min(drop, len(self) - 2)
