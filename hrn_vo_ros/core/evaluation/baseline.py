"""A classical baseline: phase correlation + Fourier–Mellin registration against an anchored map.

Public API (same step interface and output as :class:`hrn_vo_ros.core.hrn.network.HRN`)::

    BaselineConfig(width=96, height=72, canvas_width=0, canvas_height=0, mu1=0.9, mu2=0.01,
                   block_iterations=100, learn_map=True, scale=False, max_log_scale=0.4, ...)
    PhaseCorrelationBaseline(cfg=None, *, rng=None)
        .step(image, t_ns, *, gyro_delta=None) -> Estimate     # h, v (map px), r (rad), z
        .map_image() -> (H_c, W_c) float64
    config_like(resonator_cfg) -> BaselineConfig   # same frame size, map anchoring, scale
    run_baseline(t_ns, images, cfg=None) -> list[Estimate]

Per event frame I (binary, placed in the centre of a zero canvas like the HRN's input):

1. **Roll (and scale), Fourier–Mellin** (Reddy & Chatterji 1996, IEEE TIP 5(8)): the map is
   moved to the previous camera position (egocentric crop, frame-sized); the magnitude spectra
   of the windowed frame and crop (translation-invariant) are high-pass filtered, resampled
   on a log-polar grid about DC (θ over [0, π), log radius) and phase-correlated; the peak
   gives the content rotation (and log zoom). The magnitude spectrum cannot tell θ from θ + π,
   and Fourier–Mellin is fragile on sparse event frames, so the roll is chosen among the FM
   angle, its θ + π twin (each only within ±``max_roll_step_deg`` of the previous roll) and a
   local grid around the previous roll (±``local_steps`` ×
   ``local_step_deg``) by the height of the translation phase-correlation peak (step 2),
   refined by a parabola on the local grid. With the scale factor the zoom is then chosen the
   same way among the FM zoom and a local grid around the previous zoom (the roll search uses
   the previous zoom). Without it the FM peak is searched in the zero-zoom row only.
   Spectra are taken on a square zero-padded grid with a circular Hann window (a rectangular
   grid or window would not rotate with the content).
2. **Translation, phase correlation**: the frame is de-rotated (and de-zoomed) about the image
   centre, Hann-windowed, and phase-correlated with the whole map (canvas FFTs, normalised
   cross-power spectrum); the peak is refined to sub-pixel precision by a parabola through the
   peak and its neighbours on each axis. The content shift is minus the camera position.
3. **Map** (same anchoring as the HRN, paper Eq. 9): ``m ← μ1 m + μ2 m0 + (1 − μ1 − μ2) A``,
   where A is the de-rotated frame moved to the estimated camera position (a Fourier shift,
   sub-pixel), blocked for the first ``block_iterations`` frames; ``m0`` is the first frame.

With ``sphere`` (as the HRN's ``sphere.enabled``) each frame is first warped by the non-rigid
part of the camera rotation at the previous pose (:mod:`hrn_vo_ros.core.hrn.sphere`).

Output conventions (as the HRN's, see ``docs/model.md``): content moved by +a pixels
gives ``h = -a`` (camera position in the map, x right / y down); a content rotation by +b (from
+x towards +y) gives ``r = -b`` (right-handed camera roll), unwrapped; ``z`` is the log zoom of
the content (positive when the camera approaches). No IMU fusion (``gyro_delta`` is ignored).
Empty frames and frames with more than ``max_fill`` of their pixels on (noise of a still camera)
repeat the previous pose with ``valid=False``, as in the HRN.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
import scipy.fft as sfft

from hrn_vo_ros.core.configbase import param, validate
from hrn_vo_ros.core.events.frames import check_event_frame
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.shared import map_block
from hrn_vo_ros.core.hrn.sphere import SphereWarp
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.errors import TrackingError

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]


@dataclass(frozen=True, slots=True)
class BaselineConfig:
    """Phase-correlation / Fourier–Mellin baseline settings."""

    width: int = param(96, 'event frame width in pixels', lo=8, hi=4096, read_only=True)
    height: int = param(72, 'event frame height in pixels', lo=8, hi=4096, read_only=True)
    canvas_width: int = param(0, 'map canvas width (0: twice the frame width)', lo=0,
                              hi=8192, read_only=True)
    canvas_height: int = param(0, 'map canvas height (0: twice the frame height)', lo=0,
                               hi=8192, read_only=True)
    mu1: float = param(0.9, 'weight of the previous map', lo=0.0, hi=1.0)
    mu2: float = param(0.01, 'weight of the initial map (anchoring)', lo=0.0, hi=1.0)
    block_iterations: int = param(100, 'no map update during the first frames', lo=0,
                                  hi=10_000_000)
    learn_map: bool = param(True, 'update the map (false: map = first frame)')
    sphere: bool = param(False, 'warp each frame by the non-rigid part of the camera rotation '
                         "at the last pose (core/hrn/sphere.py, as the HRN's sphere.enabled)")
    focal_px: float = param(0.0, 'focal length in frame pixels (sphere correction)', lo=0.0,
                            hi=100_000.0)
    scale: bool = param(False, 'estimate the log zoom z (Fourier–Mellin scale)')
    max_log_scale: float = param(0.4, 'largest |z| accepted per frame', lo=0.01, hi=3.0)
    n_theta: int = param(180, 'log-polar angle samples over [0, pi)', lo=16, hi=4096)
    n_rho: int = param(64, 'log-polar radius samples', lo=8, hi=4096)
    max_fill: float = param(0.3, 'frames with a larger fraction of pixels on are noise (a still '
                            'camera) and are skipped, as in the HRN', lo=0.0, hi=1.0)
    blur: float = param(1.0, 'Gaussian std (pixels) applied to each event frame first (0: none)',
                        lo=0.0, hi=10.0)
    local_steps: int = param(3, 'angles tried on each side of the previous roll', lo=0,
                             hi=100)
    local_step_deg: float = param(1.5, 'spacing of the local roll search, degrees', lo=0.01,
                                  hi=45.0)
    local_zoom_step: float = param(0.02, 'spacing of the local log-zoom search (scale on)',
                                   lo=0.001, hi=1.0)
    max_roll_step_deg: float = param(30.0, 'largest roll change accepted between frames '
                                     '(gates the Fourier–Mellin candidates), degrees',
                                     lo=1.0, hi=180.0)
    peak_smoothing: float = param(0.7, 'Gaussian std (bins) applied to correlation surfaces '
                                  'before the peak search (0: none)', lo=0.0, hi=10.0)

    def __post_init__(self) -> None:
        validate(self)


def _hann2(h: int, w: int) -> F64:
    return np.outer(np.hanning(h), np.hanning(w))


def _phase_corr(A: C128, B: C128) -> F64:
    """Real correlation surface of spectra A, B (peak at the shift of b relative to a)."""
    X = np.conj(A) * B
    X /= np.maximum(np.abs(X), 1e-12)
    return np.asarray(sfft.ifft2(X).real, dtype=np.float64)


def _parabolic(c_m: float, c_0: float, c_p: float) -> float:
    den = c_m - 2 * c_0 + c_p
    if den >= 0:
        return 0.0
    return float(np.clip(0.5 * (c_m - c_p) / den, -0.5, 0.5))


def _peak2(corr: F64) -> tuple[float, float]:
    """Sub-pixel (row, col) of the maximum of a periodic surface, in (-N/2, N/2]."""
    h, w = corr.shape
    r, c = np.unravel_index(int(np.argmax(corr)), corr.shape)
    dr = _parabolic(corr[(r - 1) % h, c], corr[r, c], corr[(r + 1) % h, c])
    dc = _parabolic(corr[r, (c - 1) % w], corr[r, c], corr[r, (c + 1) % w])
    rr = (r + dr + h / 2) % h - h / 2
    cc = (c + dc + w / 2) % w - w / 2
    return float(rr), float(cc)


class PhaseCorrelationBaseline:
    """Frame-to-map registration by phase correlation and Fourier–Mellin (module docstring).

    Args:
        cfg: Settings (96x72 frames by default).
        rng: Unused (the baseline is deterministic); accepted for the HRN-like constructor.
    """

    def __init__(self, cfg: BaselineConfig | None = None, *,
                 rng: np.random.Generator | None = None) -> None:
        self.cfg = cfg if cfg is not None else BaselineConfig()
        c = self.cfg
        self.W = c.canvas_width or 2 * c.width
        self.H = c.canvas_height or 2 * c.height
        if c.width > self.W or c.height > self.H:
            raise TrackingError('the canvas must be at least as large as the frame')
        self.ox = (self.W - c.width) // 2
        self.oy = (self.H - c.height) // 2
        self._sphere = SphereWarp(c.width, c.height, c.focal_px) if c.sphere else None
        self.win = _hann2(c.height, c.width)
        # frequency grids for Fourier shifts of the canvas
        self.fy = sfft.fftfreq(self.H)[:, None]
        self.fx = sfft.fftfreq(self.W)[None, :]
        self._make_logpolar()
        self.reset()

    def _make_logpolar(self) -> None:
        c = self.cfg
        h, w = c.height, c.width
        # square, isotropic spectrum grid: a rotation of the content is a rotation of the
        # spectrum only if both axes have the same frequency spacing
        self.sq = int(2 ** math.ceil(math.log2(max(h, w))))
        rad = 0.5 * min(h, w)
        yy, xx = np.mgrid[0:h, 0:w]
        rr = np.hypot(yy - (h - 1) / 2, xx - (w - 1) / 2) / rad
        self.cwin = np.where(rr < 1.0, 0.5 * (1 + np.cos(np.pi * np.minimum(rr, 1.0))), 0.0)
        n = self.sq
        r_min, r_max = 2.0, 0.5 * n
        self.log_base = math.log(r_max / r_min) / c.n_rho
        rho = r_min * np.exp(np.arange(c.n_rho) * self.log_base)
        theta = np.arange(c.n_theta) * math.pi / c.n_theta
        self.lp_rows = (n / 2 + rho[:, None] * np.sin(theta)[None, :]).ravel()
        self.lp_cols = (n / 2 + rho[:, None] * np.cos(theta)[None, :]).ravel()
        f = sfft.fftshift(sfft.fftfreq(n))
        cosx = np.cos(2 * np.pi * f[None, :]) * np.cos(2 * np.pi * f[:, None])
        self.highpass = (1.0 - cosx) * (2.0 - cosx)   # Reddy & Chatterji's emphasis filter

    def reset(self) -> None:
        """Forget the map and the pose."""
        self.map = np.zeros((self.H, self.W))
        self.map0 = np.zeros((self.H, self.W))
        self.started = False
        self.iteration = 0
        self.h = self.v = self.r = self.z = 0.0
        self._last: Estimate | None = None

    # -- pieces ------------------------------------------------------------------------------

    def _logpolar_spectrum(self, img: F64) -> C128:
        c = self.cfg
        n = self.sq
        pad = np.zeros((n, n))
        oy, ox = (n - c.height) // 2, (n - c.width) // 2
        pad[oy:oy + c.height, ox:ox + c.width] = img * self.cwin
        mag = np.abs(sfft.fftshift(sfft.fft2(pad)))
        mag = np.log1p(mag) * self.highpass
        lp = ndimage.map_coordinates(mag, [self.lp_rows, self.lp_cols], order=1,
                                     mode='nearest').reshape(c.n_rho, c.n_theta)
        return np.asarray(sfft.fft2(lp), dtype=np.complex128)

    def _egocentric_crop(self) -> F64:
        """The map moved to the current camera position, frame-sized (no rotation)."""
        M = sfft.fft2(self.map)
        ramp = np.exp(-2j * np.pi * (self.fx * (-self.h) + self.fy * (-self.v)))
        moved = sfft.ifft2(M * ramp).real
        return np.asarray(moved[self.oy:self.oy + self.cfg.height,
                                self.ox:self.ox + self.cfg.width], dtype=np.float64)

    def _rotation_scale(self, img: F64) -> tuple[float, float]:
        """Content rotation (rad, +x towards +y) and log zoom of ``img`` relative to the map."""
        c = self.cfg
        A = self._logpolar_spectrum(self._egocentric_crop())
        B = self._logpolar_spectrum(img)
        corr = _phase_corr(A, B)
        if c.peak_smoothing > 0:
            corr = ndimage.gaussian_filter(corr, c.peak_smoothing, mode='wrap')
        if c.scale:
            lim = int(min(c.max_log_scale / self.log_base, c.n_rho // 2 - 1))
            rows = np.r_[0:lim + 1, c.n_rho - lim:c.n_rho]
            sub = np.full_like(corr, -np.inf)
            sub[rows] = corr[rows]
            drho, dth = _peak2(np.where(np.isfinite(sub), sub, corr.min()))
        else:
            row = corr[0]
            k = int(np.argmax(row))
            n = len(row)
            dth = k + _parabolic(row[(k - 1) % n], row[k], row[(k + 1) % n])
            dth = (dth + n / 2) % n - n / 2
            drho = 0.0
        angle = dth * math.pi / c.n_theta          # content rotation modulo pi
        # content zoomed by e^z shrinks the spectrum: the log-radius shift is -z / log_base
        return float(angle), float(-drho * self.log_base)

    def _register(self, img: F64, angle: float, zoom: float, M: C128) -> tuple[float, F64]:
        """Peak height and translation correlation surface of the de-rotated frame vs. map."""
        c = self.cfg
        canvas = np.zeros((self.H, self.W))
        canvas[self.oy:self.oy + c.height, self.ox:self.ox + c.width] = (
            self._warp(img, angle, zoom) * self.win)
        corr = _phase_corr(sfft.fft2(canvas), M)
        if c.peak_smoothing > 0:
            corr = ndimage.gaussian_filter(corr, c.peak_smoothing, mode='wrap')
        return float(corr.max()), corr

    def _warp(self, img: F64, angle: float, log_zoom: float) -> F64:
        """Rotate ``img`` by -angle and zoom by exp(-log_zoom) about the image centre."""
        h, w = img.shape
        ca, sa = math.cos(angle), math.sin(angle)
        s = math.exp(log_zoom)
        # output pixel p samples input at centre + s R(angle) (p - centre)
        M = s * np.array([[ca, sa], [-sa, ca]])  # (row, col) order: rotation +x -> +y
        centre = np.array([(h - 1) / 2, (w - 1) / 2])
        offset = centre - M @ centre
        return np.asarray(ndimage.affine_transform(img, M, offset=offset, order=1,
                                                   mode='constant', cval=0.0), dtype=np.float64)

    # -- public ------------------------------------------------------------------------------

    def step(self, image: NDArray[np.generic], t_ns: int, *,
             gyro_delta: NDArray[np.generic] | None = None) -> Estimate:
        """Register one event frame against the map; returns the pose (see module docstring).

        Shapes:
            image: (height, width).

        Raises:
            TrackingError: for a frame of the wrong shape or with non-finite values.
        """
        c = self.cfg
        img, usable = check_event_frame(image, c.width, c.height, c.max_fill, 'baseline')
        if not usable:
            return self._emit(t_ns, valid=False)
        if self._sphere is not None and self.started:
            img = self._sphere.warp(img, self.h, self.v, self.r)
        if c.blur > 0:
            img = ndimage.gaussian_filter(img, c.blur, mode='constant')
        if not self.started:
            self.map[self.oy:self.oy + c.height, self.ox:self.ox + c.width] = img
            self.map0 = self.map.copy()
            self.started = True
            self.iteration = 1
            return self._emit(t_ns, valid=True)
        self.iteration += 1
        angle, log_zoom = self._rotation_scale(img)
        fm_zoom = float(np.clip(log_zoom, -c.max_log_scale, c.max_log_scale))
        # candidates: the Fourier–Mellin angle and its θ + π twin (the magnitude spectrum cannot
        # tell them apart), and a local search around the previous angle; the one whose
        # de-rotated frame gives the highest translation peak wins
        prev = -self.r
        base = angle + math.pi * round((prev - angle) / math.pi)
        step = math.radians(c.local_step_deg)
        local = [prev + k * step for k in range(-c.local_steps, c.local_steps + 1)]
        M = sfft.fft2(self.map)
        gate = math.radians(c.max_roll_step_deg)
        far = [a for a in (base, base + math.pi) if abs(a - prev) <= gate]
        zoom = self.z if c.scale else 0.0
        results = [(*self._register(img, cand, zoom, M), cand) for cand in [*far, *local]]
        k_best = int(np.argmax([r[0] for r in results]))
        height, corr, cand = results[k_best]
        k0 = len(far)
        if k0 < k_best < k0 + len(local) - 1:   # refine inside the local grid
            cand += step * _parabolic(results[k_best - 1][0], height, results[k_best + 1][0])
        if c.scale:
            # the same for the zoom: the Fourier–Mellin zoom and a local grid around the last
            zs = [self.z + k * c.local_zoom_step for k in range(-2, 3)]
            zres = [(*self._register(img, cand, zz, M), zz) for zz in [fm_zoom, *zs]]
            kz = int(np.argmax([r[0] for r in zres]))
            height, corr, zoom = zres[kz]
            if 1 < kz < len(zres) - 1:
                zoom += c.local_zoom_step * _parabolic(zres[kz - 1][0], height, zres[kz + 1][0])
            zoom = float(np.clip(zoom, -c.max_log_scale, c.max_log_scale))
        dy, dx = _peak2(corr)
        self.z = zoom
        self.r = -(prev + ((cand - prev + math.pi) % (2 * math.pi) - math.pi))
        # corr peaks at the shift of the map relative to the frame: map = frame moved by (dy, dx)
        # i.e. the frame is the map content moved by (-dx, -dy): camera at (dx, dy)
        self.h, self.v = dx, dy
        if c.learn_map and self.iteration > c.block_iterations:
            ramp = np.exp(-2j * np.pi * (self.fx * self.h + self.fy * self.v))
            unwin = np.zeros((self.H, self.W))
            unwin[self.oy:self.oy + c.height, self.ox:self.ox + c.width] = self._warp(
                img, -self.r, self.z if c.scale else 0.0)
            aligned = sfft.ifft2(sfft.fft2(unwin) * ramp).real
            a = 1.0 - c.mu1 - c.mu2
            self.map = c.mu1 * self.map + c.mu2 * self.map0 + a * aligned
            return self._emit(t_ns, valid=True, updated=True)
        return self._emit(t_ns, valid=True)

    def _emit(self, t_ns: int, *, valid: bool, updated: bool = False) -> Estimate:
        est = Estimate(t_ns=int(t_ns), h=self.h, v=self.v, r=self.r, z=self.z,
                       iteration=self.iteration, map_updated=updated, valid=valid)
        self._last = est
        return est

    def map_image(self) -> F64:
        """The map (canvas-sized intensity image)."""
        return self.map.copy()


def config_like(rcfg: ResonatorConfig) -> BaselineConfig:
    """Baseline settings matching an HRN config: frame size, map anchoring, sphere correction
    and scale factor.

    The HRN blocks its map for ``map.block_iterations`` resonator iterations (``map_block``:
    ``imu.block_iterations`` with the gyro), the baseline for that many frames: the count is
    divided by ``cleanup.iterations_per_frame`` so that both start learning their maps on the
    same frame.
    """
    per_frame = rcfg.cleanup.iterations_per_frame       # >= 1 (validated)
    return BaselineConfig(width=rcfg.width, height=rcfg.height, mu1=rcfg.map.mu1,
                          mu2=rcfg.map.mu2,
                          block_iterations=map_block(rcfg) // per_frame,
                          learn_map=rcfg.map.learn, sphere=rcfg.sphere.enabled,
                          focal_px=rcfg.focal_px, scale=rcfg.scale.enabled,
                          max_log_scale=rcfg.scale.max_log_scale, max_fill=rcfg.max_fill)


def run_baseline(t_ns: NDArray[np.int64], images: NDArray[np.generic],
                 cfg: BaselineConfig | None = None) -> list[Estimate]:
    """Run the baseline over a stack of event frames.

    Shapes:
        t_ns: (n,); images: (n, height, width).
    """
    base = PhaseCorrelationBaseline(cfg)
    return [base.step(images[i], int(t_ns[i])) for i in range(len(t_ns))]
