"""Camera motions of the simulator: smooth random signals, hand-held rotation, translation
in front of a wall and a robot arm's arcs.

A motion maps times ``t`` (seconds, shape (n,)) to camera-to-world rotations (n, 3, 3) and
camera centres (n, 3) in the world frame of its scene.
"""

from __future__ import annotations

from collections.abc import Callable
import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.odometry.geometry import euler_ptr_to_matrix, rot_z

F64 = NDArray[np.float64]


class Smooth:
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


class RotationMotion:
    """Hand-held 3-DoF rotation about the camera centre (plus a few mm of hand translation)."""

    def __init__(self, rng: np.random.Generator, seconds: float, speed: float) -> None:
        deg = np.pi / 180.0
        ramp = (1.0 * speed, 9.0 * speed, 0.6)
        self.limits = (20 * deg * rng.uniform(0.85, 1.0), 20 * deg * rng.uniform(0.85, 1.0),
                       50 * deg * rng.uniform(0.85, 1.0))
        self.angles = [Smooth(rng, seconds, f_lo=0.1, f_hi=0.4, ramp=ramp) for _ in range(3)]
        self.hand = [Smooth(rng, seconds, f_lo=0.3, f_hi=1.2, ramp=(speed, 2 * speed, 1.0))
                     for _ in range(3)]

    def __call__(self, t: F64) -> tuple[F64, F64]:
        pan, tilt, roll = (lim * s(t) for lim, s in zip(self.limits, self.angles, strict=True))
        R = euler_ptr_to_matrix(pan, tilt, roll)
        c = np.stack([0.004 * s(t) for s in self.hand], axis=-1)
        return R, c


class TranslationMotion:
    """x/y/z translation in front of the wall with a little roll and pan/tilt wobble."""

    def __init__(self, rng: np.random.Generator, seconds: float, speed: float) -> None:
        deg = np.pi / 180.0
        ramp = (1.0 * speed, 5.0 * speed, 0.6)
        self.amp = np.array([0.30, 0.22, 0.15]) * rng.uniform(0.85, 1.0, 3)
        self.pos = [Smooth(rng, seconds, f_lo=0.1, f_hi=0.4, ramp=ramp) for _ in range(3)]
        self.roll_lim = 8 * deg * rng.uniform(0.8, 1.0)
        self.roll = Smooth(rng, seconds, f_lo=0.1, f_hi=0.4, ramp=ramp)
        self.wobble = [Smooth(rng, seconds, f_lo=0.2, f_hi=0.8, ramp=ramp) for _ in range(2)]

    def __call__(self, t: F64) -> tuple[F64, F64]:
        deg = np.pi / 180.0
        R = euler_ptr_to_matrix(0.5 * deg * self.wobble[0](t), 0.5 * deg * self.wobble[1](t),
                                self.roll_lim * self.roll(t))
        c = np.stack([a * s(t) for a, s in zip(self.amp, self.pos, strict=True)], axis=-1)
        return R, c


class ArmMotion:
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
        self.wobble = [Smooth(rng, seconds, f_lo=0.5, f_hi=2.0, ramp=(1.0, 1.0, 1.0))
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


class Progress:
    """Phase time of a ramped motion with pauses: ``τ(t) = ∫ g``, ``u(t) = τ(t) / τ(T)``.

    The rate ``g`` rises linearly from ``1`` to ``speed_ratio`` over the sequence (faster at the
    end, as in the Event Camera Dataset) and drops smoothly to 0 (raised-cosine edges of 0.1 s)
    in each pause ``(start, duration)``: everything that depends on τ only stands still there.
    τ is tabulated every 0.5 ms and interpolated linearly.
    """

    def __init__(self, seconds: float, speed_ratio: float,
                 pauses: tuple[tuple[float, float], ...]) -> None:
        self.T = max(seconds, 1e-3)
        grid = np.linspace(0.0, self.T, int(math.ceil(self.T / 5e-4)) + 1)
        g = 1.0 + (speed_ratio - 1.0) * grid / self.T
        edge = 0.1
        for start, dur in pauses:
            d = np.clip(np.minimum(grid - start, start + dur - grid) / edge, 0.0, 1.0)
            g = g * (1.0 - 0.5 * (1.0 - np.cos(np.pi * d)))
        tau = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(grid))])
        self.grid, self.tau, self.g = grid, tau, g
        self.total = float(tau[-1]) if tau[-1] > 0 else 1.0

    def __call__(self, t: F64) -> tuple[F64, F64]:
        """Phase time τ (seconds at unit rate, continued linearly outside [0, T]) and u."""
        tau = np.interp(t, self.grid, self.tau)
        tau = tau + np.where(t > self.T, self.g[-1], 0.0) * (t - self.T)
        tau = tau + np.where(t < 0.0, self.g[0], 0.0) * t
        return tau, np.clip(tau / self.total, 0.0, 1.0)


class Wave:
    """``Σ a_k sin(2π f_k k_rate τ + φ_k)`` normalised to [-1, 1] (a smooth random signal in τ),
    optionally plus a faster, smaller ``jerk`` component (hand jitter, jerky motion)."""

    def __init__(self, rng: np.random.Generator, *, f_lo: float, f_hi: float, jerk: float,
                 n: int = 3) -> None:
        self.f = rng.uniform(f_lo, f_hi, n)
        self.phase = rng.uniform(0.0, 2 * np.pi, n)
        self.amp = rng.uniform(0.4, 1.0, n)
        self.f_j = rng.uniform(6 * f_lo, 8 * f_hi, 4)
        self.phase_j = rng.uniform(0.0, 2 * np.pi, 4)
        self.amp_j = jerk * rng.uniform(0.3, 1.0, 4) * np.sum(self.amp) / 4
        self.rate = 1.0
        self.norm = float(np.sum(self.amp) + np.sum(self.amp_j))

    def __call__(self, tau: F64) -> F64:
        x = 2 * np.pi * self.rate * tau
        s = np.sum(self.amp[:, None] * np.sin(self.f[:, None] * x[None, :]
                                              + self.phase[:, None]), axis=0)
        s = s + np.sum(self.amp_j[:, None] * np.sin(self.f_j[:, None] * x[None, :]
                                                    + self.phase_j[:, None]), axis=0)
        return np.asarray(s / self.norm, dtype=np.float64)


class RampedMotion:
    """Hand-held rotation or translation whose amplitude and speed ramp up, with pauses.

    Angles (pan, tilt, roll; swing about the camera centre) and the camera centre are
    ``limit * env(u) * wave(τ)`` with ``env(u) = env0 + (1 - env0) u`` (amplitudes grow over the
    sequence as in the Event Camera Dataset's shapes sequences) and τ, u from
    :class:`Progress`. :meth:`set_peak` rescales the waves' frequencies so that the peak
    angular (``'deg_s'``) or linear (``'m_s'``) speed of the sequence hits a target.
    """

    def __init__(self, rng: np.random.Generator, progress: Progress, *,
                 angle_limits: tuple[float, float, float], offsets: tuple[float, float, float],
                 env0: float, jerk: float) -> None:
        self.progress = progress
        self.angle_limits = np.asarray(angle_limits, dtype=np.float64)
        self.offsets = np.asarray(offsets, dtype=np.float64)
        self.env0 = env0
        self.angles = [Wave(rng, f_lo=0.1, f_hi=0.4, jerk=jerk) for _ in range(3)]
        self.pos = [Wave(rng, f_lo=0.1, f_hi=0.4, jerk=jerk) for _ in range(3)]

    def __call__(self, t: F64) -> tuple[F64, F64]:
        tau, u = self.progress(np.asarray(t, dtype=np.float64))
        env = self.env0 + (1.0 - self.env0) * u
        pan, tilt, roll = (lim * env * w(tau)
                           for lim, w in zip(self.angle_limits, self.angles, strict=True))
        R = euler_ptr_to_matrix(pan, tilt, roll)
        c = np.stack([a * env * w(tau) for a, w in zip(self.offsets, self.pos, strict=True)],
                     axis=-1)
        return R, c

    def peak_speed(self, unit: str) -> float:
        """Largest angular speed (deg/s, ``unit='deg_s'``) or linear speed (m/s) over [0, T]."""
        t = np.linspace(0.0, self.progress.T, int(self.progress.T * 1000) + 2)
        R, c = self(t)
        dt = float(t[1] - t[0])
        if unit == 'deg_s':
            rel = np.einsum('nji,njk->nik', R[:-1], R[1:])
            cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
            return float(np.degrees(np.max(np.arccos(cos))) / dt)
        return float(np.max(np.linalg.norm(np.diff(c, axis=0), axis=1)) / dt)

    def set_peak(self, target: float, unit: str) -> None:
        """Rescale the wave rates so that :meth:`peak_speed` is ``target`` (within 1 %).

        The peak is continuous in the rate but not monotonic (its place moves), so a crossing
        is bracketed by doubling or halving the rate and then bisected on log rate.
        """
        waves = (*self.angles, *self.pos)

        def peak_at(k: float) -> float:
            for w in waves:
                w.rate = k
            return self.peak_speed(unit)

        lo = hi = 1.0
        p = peak_at(1.0)
        for _ in range(30):
            if p >= target:
                break
            lo, hi = hi, hi * 2.0
            p = peak_at(hi)
        if hi == 1.0:
            for _ in range(30):
                if p <= target:
                    break
                hi, lo = lo, lo / 2.0
                p = peak_at(lo)
        for _ in range(40):
            mid = math.sqrt(lo * hi)
            p = peak_at(mid)
            if abs(p / target - 1.0) < 0.01:
                return
            if p < target:
                lo = mid
            else:
                hi = mid
