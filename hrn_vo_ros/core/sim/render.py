"""Rendering of a scene and the event generator (per-pixel threshold crossings, noise).

See :mod:`hrn_vo_ros.core.sim.simulator` for the event model.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.camera import undistort_points
from hrn_vo_ros.core.events.sequence import CameraCalibration
from hrn_vo_ros.core.sim.config import HOT_RATE_RANGE, LOG_EPS, SimulatorConfig
from hrn_vo_ros.core.sim.motion import Motion
from hrn_vo_ros.core.sim.textures import Texture

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]


@dataclass(frozen=True, slots=True)
class Scene:
    """Camera, textured plane z = ``plane_z`` (world) and camera motion of one simulated kind."""

    kind: str
    calib: CameraCalibration
    texture: Texture
    plane_z: float
    motion: Motion
    gravity: tuple[float, float, float]
    render_px_scale: float = 1.0


def undistort_calib(calib: CameraCalibration, u: F64, v: F64) -> tuple[F64, F64]:
    """Normalised undistorted coordinates of distorted pixel coordinates."""
    return undistort_points(calib.fx, calib.fy, calib.cx, calib.cy, calib.dist, u, v)


class Renderer:
    """Log irradiance of every pixel for a batch of times."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        c = scene.calib
        vv, uu = np.mgrid[0:c.height, 0:c.width].astype(np.float64)
        x, y = undistort_calib(c, uu.ravel(), vv.ravel())
        self.rays = np.stack([x, y, np.ones_like(x)], axis=1)  # (N, 3) camera frame
        self.rays_t = np.ascontiguousarray(self.rays.T, dtype=np.float32)  # (3, N)
        self.log_tex = np.log(scene.texture.image + np.float32(LOG_EPS)).astype(np.float32)
        self.log_flat = self.log_tex.ravel()
        # sparse probe points for the adaptive render rate
        gu, gv = np.meshgrid(np.linspace(0, c.width - 1, 9), np.linspace(0, c.height - 1, 7))
        px, py = undistort_calib(c, gu.ravel(), gv.ravel())
        self.probes = np.stack([px, py, np.ones_like(px)], axis=1)

    def plane_points(self, R: F64, c: F64, rays: F64) -> tuple[F64, F64]:
        """Plane coordinates hit by ``rays`` (camera frame) from poses (R, c).

        Shapes:
            R: (B, 3, 3); c: (B, 3); rays: (N, 3); returns two (B, N) arrays.
        """
        d = np.einsum('bij,nj->bni', R, rays)
        dz = d[..., 2]
        dz = np.where(np.abs(dz) < 1e-9, 1e-9, dz)
        lam = (self.scene.plane_z - c[:, 2, None]) / dz
        lam = np.maximum(lam, 0.0)
        return c[:, 0, None] + lam * d[..., 0], c[:, 1, None] + lam * d[..., 1]

    def render(self, t: F64) -> F32:
        """Log intensity ``log(I + 0.02)`` at times ``t``. Shapes: t (B,) -> (B, N) float32.

        The plane is mapped to the image by a homography per time: with ray r (camera frame),
        d = R r and lam = (z_plane - c_z) / d_z, the plane point is c + lam d, i.e.
        col = ((c_x - x0) d_z + (z_plane - c_z) d_x) / (texel d_z) (rows likewise): one small
        matrix product for all pixels and renders, then a bilinear texture lookup.
        """
        R, c = self.scene.motion(t)
        tex = self.scene.texture
        dz_w = self.scene.plane_z - c[:, 2]
        M = np.empty((len(t), 3, 3))
        M[:, 0] = ((c[:, 0] - tex.x0)[:, None] * R[:, 2] + dz_w[:, None] * R[:, 0]) / tex.texel
        M[:, 1] = ((c[:, 1] - tex.y0)[:, None] * R[:, 2] + dz_w[:, None] * R[:, 1]) / tex.texel
        M[:, 2] = R[:, 2]
        P = (M.reshape(-1, 3).astype(np.float32) @ self.rays_t).reshape(len(t), 3, -1)
        den = P[:, 2]
        den[np.abs(den) < 1e-6] = 1e-6
        col = P[:, 0] / den
        row = P[:, 1] / den
        return self._bilinear(row, col)

    def _bilinear(self, row: F32, col: F32) -> F32:
        """Bilinear lookup in the log texture (coordinates clamped to the texture)."""
        img = self.log_tex
        h, w = img.shape
        np.clip(col, 0, w - 1.001, out=col)
        np.clip(row, 0, h - 1.001, out=row)
        ic = col.astype(np.int32)
        ir = row.astype(np.int32)
        col -= ic
        row -= ir
        flat = ir * np.int32(w)
        flat += ic
        v00 = self.log_flat[flat]
        v01 = self.log_flat[flat + 1]
        flat += np.int32(w)
        v10 = self.log_flat[flat]
        v11 = self.log_flat[flat + 1]
        v01 -= v00
        v01 *= col
        v00 += v01
        v11 -= v10
        v11 *= col
        v10 += v11
        v10 -= v00
        v10 *= row
        v00 += v10
        return np.asarray(v00, dtype=np.float32)

    def motion_px(self, t: F64) -> F64:
        """Largest image motion (pixels) of the probe points between consecutive times.

        Shapes:
            t: (n,); returns (n - 1,).
        """
        R, c = self.scene.motion(t)
        X, Y = self.plane_points(R, c, self.probes)
        P = np.stack([X[:-1], Y[:-1], np.full_like(X[:-1], self.scene.plane_z)], axis=-1)
        cam = np.einsum('bji,bnj->bni', R[1:], P - c[1:, None, :])
        z = np.maximum(cam[..., 2], 1e-6)
        calib = self.scene.calib
        u = calib.fx * cam[..., 0] / z
        v = calib.fy * cam[..., 1] / z
        u0 = calib.fx * self.probes[:, 0]
        v0 = calib.fy * self.probes[:, 1]
        return np.asarray(np.max(np.hypot(u - u0, v - v0), axis=1), dtype=np.float64)


def render_times(renderer: Renderer, seconds: float, cfg: SimulatorConfig) -> F64:
    """Adaptive render times in [0, seconds]: ≤ max_px_per_render of motion between renders."""
    base_dt = 2.5e-4
    tb = np.linspace(0.0, seconds, int(math.ceil(seconds / base_dt)) + 1)
    step = np.empty(len(tb) - 1)
    for i0 in range(0, len(tb) - 1, 20000):
        seg = tb[i0:i0 + 20001]
        step[i0:i0 + len(seg) - 1] = renderer.motion_px(seg)
    cum = np.concatenate([[0.0], np.cumsum(step)])
    n_motion = int(math.ceil(cum[-1] / (cfg.max_px_per_render
                                        * renderer.scene.render_px_scale)))
    t_motion = np.interp(np.linspace(0.0, cum[-1], n_motion + 1), cum, tb)
    t_min = np.linspace(0.0, seconds, int(math.ceil(seconds * cfg.min_render_rate_hz)) + 1)
    t = np.unique(np.concatenate([t_motion, t_min]))
    # drop renders closer than 2 µs (identical images)
    keep = np.concatenate([[True], np.diff(t) > 2e-6])
    t = np.asarray(t[keep], dtype=np.float64)
    t[-1] = seconds
    return t


class EventGenerator:
    """Per-pixel contrast-threshold crossing with mismatch and a refractory period."""

    def __init__(self, n_pix: int, cfg: SimulatorConfig, rng: np.random.Generator,
                 L0: F32) -> None:
        c = cfg.contrast_threshold
        self.c_on = np.maximum(rng.normal(c, cfg.threshold_sigma, n_pix), cfg.min_threshold)
        self.c_off = np.maximum(rng.normal(c, cfg.threshold_sigma, n_pix), cfg.min_threshold)
        # arbitrary reset state at the start: the reference sits somewhere inside its band
        self.ref = L0.astype(np.float64) + rng.uniform(-0.5, 0.5, n_pix) * np.minimum(
            self.c_on, self.c_off)
        self.last = np.full(n_pix, -1.0)
        self.refr = cfg.refractory_s

    def step(self, L0: F32, L1: F32, t0: float, t1: float,
             out: list[tuple[NDArray[np.intp], F64, NDArray[np.bool_]]]) -> None:
        """Emit the events of the interval (t0, t1] where log intensity goes from L0 to L1."""
        d = L1 - self.ref
        pos = d >= self.c_on
        neg = d <= -self.c_off
        idx = np.flatnonzero(pos | neg)
        if idx.size == 0:
            return
        up = pos[idx]
        sgn = np.where(up, 1.0, -1.0)
        C = np.where(up, self.c_on[idx], self.c_off[idx])
        n = np.floor(np.abs(d[idx]) / C).astype(np.int64)
        l0 = L0[idx].astype(np.float64)
        dl = L1[idx].astype(np.float64) - l0
        dl = np.where(np.abs(dl) < 1e-12, 1e-12, dl)
        base = self.ref[idx]
        dt = t1 - t0
        sel_idx, sel_sgn, sel_C, sel_base, sel_l0, sel_dl = idx, sgn, C, base, l0, dl
        sel_n = n
        for k in range(1, int(n.max()) + 1):
            if k > 1:
                m = sel_n >= k
                sel_idx, sel_sgn, sel_C = sel_idx[m], sel_sgn[m], sel_C[m]
                sel_base, sel_l0, sel_dl, sel_n = sel_base[m], sel_l0[m], sel_dl[m], sel_n[m]
            level = sel_base + sel_sgn * k * sel_C
            frac = np.clip((level - sel_l0) / sel_dl, 0.0, 1.0)
            tk = t0 + frac * dt
            ok = tk - self.last[sel_idx] >= self.refr
            if np.any(ok):
                pix = sel_idx[ok]
                self.last[pix] = tk[ok]
                out.append((pix, tk[ok], sel_sgn[ok] > 0))
        self.ref[idx] = base + sgn * n * C


def noise_events(rng: np.random.Generator, n_pix: int, hot: NDArray[np.intp],
                  hot_rates: F64, t0: float, t1: float,
                  cfg: SimulatorConfig) -> tuple[NDArray[np.intp], F64, NDArray[np.bool_]]:
    """Background activity and hot-pixel events in (t0, t1]."""
    dur = t1 - t0
    n_ba = int(rng.poisson(cfg.noise_rate_hz * n_pix * dur))
    pix = [rng.integers(0, n_pix, n_ba)]
    counts = rng.poisson(hot_rates * dur)
    pix.append(np.repeat(hot, counts))
    allpix = np.concatenate(pix).astype(np.intp)
    t = t1 - rng.uniform(0.0, dur, allpix.size)
    pol = rng.random(allpix.size) < 0.5
    return allpix, t, pol


def simulate_events(scene: Scene, seconds: float, cfg: SimulatorConfig, rng: np.random.Generator,
                    progress: Callable[[float], None] | None = None) -> EventArray:
    """Events of ``scene`` in (0, seconds]: renders, threshold crossings, noise, quantisation.

    Args:
        scene: Camera, textured plane and motion.
        seconds: Duration, seconds.
        cfg: Sensor, noise and rendering parameters.
        rng: Draws the per-pixel thresholds, the initial references, the hot pixels and the
            noise events (in this order).
        progress: Called with the number of simulated seconds completed since the last call.

    Returns:
        The events, sorted by time.
    """
    renderer = Renderer(scene)
    times = render_times(renderer, seconds, cfg)
    calib = scene.calib
    n_pix = calib.width * calib.height
    L_prev = renderer.render(times[:1])[0]
    gen = EventGenerator(n_pix, cfg, rng, L_prev)
    hot = rng.choice(n_pix, size=min(cfg.hot_pixels, n_pix), replace=False).astype(np.intp)
    hot_rates = cfg.hot_pixel_rate_hz * rng.uniform(*HOT_RATE_RANGE, hot.size)
    quantum = cfg.timestamp_resolution_s
    parts_t: list[NDArray[np.int64]] = []
    parts_pix: list[NDArray[np.intp]] = []
    parts_p: list[NDArray[np.bool_]] = []
    B = max(1, min(cfg.render_batch, cfg.render_pixels // n_pix))
    done = 0.0
    for b0 in range(1, len(times), B):
        tb = times[b0:b0 + B]
        Ls = renderer.render(tb)
        out: list[tuple[NDArray[np.intp], F64, NDArray[np.bool_]]] = []
        t_prev = float(times[b0 - 1])
        for j in range(len(tb)):
            gen.step(L_prev, Ls[j], t_prev, float(tb[j]), out)
            L_prev = Ls[j]
            t_prev = float(tb[j])
        out.append(noise_events(rng, n_pix, hot, hot_rates, float(times[b0 - 1]),
                                float(tb[-1]), cfg))
        pix = np.concatenate([o[0] for o in out])
        ts = np.concatenate([o[1] for o in out])
        pol = np.concatenate([o[2] for o in out])
        tq = (np.floor(ts / quantum + 1e-6) * (quantum * 1e9)).astype(np.int64)
        order = np.argsort(tq, kind='stable')
        parts_t.append(tq[order])
        parts_pix.append(pix[order])
        parts_p.append(pol[order])
        if progress is not None:
            progress(float(tb[-1]) - done)
            done = float(tb[-1])
    t_all = np.concatenate(parts_t) if parts_t else np.empty(0, np.int64)
    pix_all = np.concatenate(parts_pix) if parts_pix else np.empty(0, np.intp)
    p_all = np.concatenate(parts_p) if parts_p else np.empty(0, bool)
    return EventArray.from_arrays(t_all, pix_all % calib.width, pix_all // calib.width,
                                  p_all.astype(np.uint8))
