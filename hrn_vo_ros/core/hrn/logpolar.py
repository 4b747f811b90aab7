"""The log-polar grid and the transforms Λ (Cartesian → log-polar) and Λ' (back); docs/model.md.

Grids:

* **Cartesian canvas**: ``W_c x H_c`` pixels, vector layout (H_c, W_c) row-major; the event image
  (``W x H``) sits at ``offset = ((W_c - W) // 2, (H_c - H) // 2)``.
* **Log-polar grid**: ``n_rho x n_theta`` samples, layout (n_rho, n_theta) row-major, centred on
  the image centre ``c = offset + ((W - 1)/2, (H - 1)/2)``:
  ``θ_k = 2π k / n_theta``, ``ρ_j = r_min · exp(j Δ)``, ``Δ = ln(r_max / r_min) / (n_rho - 1)``.
  θ is measured from +x towards +y (y points down), so a positive θ shift is a clockwise rotation
  of the image content as displayed.

Resampling matrices (scipy.sparse CSR, real, ≤ 4 bilinear weights per row):

* ``T`` (N_LP x N_C): row (j, k) interpolates the canvas at ``c + ρ_j (cos θ_k, sin θ_k)``
  (neighbours outside the canvas count as 0).
* ``T'`` (N_C x N_LP): row (x, y) interpolates the log-polar grid at
  ``(ln(ρ/r_min)/Δ, θ/(2π/n_θ))`` with θ circular; pixels inside ``r_min`` take the inner ring,
  pixels beyond ``r_max`` are 0.
  T' is *not* pinv(T) (the grid over-samples the centre and drops the corners beyond r_max); we
  use T' as the resampler of Λ' (the inverse direction) instead.

Λ and Λ':

* dense, any codebooks: ``Λ = Φ_LP T Φ_C⁺``, ``Λ' = Φ_C T' Φ_LP⁺`` (:func:`dense_lambdas`);
* with DFT codebooks (Φ = 2-D DFT): ``Λ x = fft2_LP(T · ifft2_C(x))``,
  ``Λ' y = fft2_C(T' · ifft2_LP(y))`` (:class:`LogPolarTransform`), the same matrices applied
  in O(N log N).
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
import scipy.fft as sfft
import scipy.sparse as sp

from hrn_vo_ros.core.configbase import param, validate
from hrn_vo_ros.core.hrn import fft as hfft
from hrn_vo_ros.errors import ConfigError

Complex = NDArray[np.complex128]


def _load_matvec() -> Any:
    """scipy's CSR matrix-vector kernel if it reproduces ``@``, else None."""
    try:
        from scipy.sparse import _sparsetools
        a = sp.csr_matrix(np.array([[1.0, 0.0, 2.5], [0.0, -1.0, 0.5]], np.complex64))
        x = np.array([1 + 2j, 3 - 1j, -0.5j], np.complex64)
        y = np.zeros(2, np.complex64)
        _sparsetools.csr_matvec(2, 3, a.indptr, a.indices, a.data, x, y)
        return _sparsetools.csr_matvec if np.array_equal(y, a @ x) else None
    except Exception:          # any failure means: use the public API
        return None


# scipy.sparse's ``A @ x`` checks and dispatches for a few µs before it calls this kernel; the
# HRN step makes six products (Λ, Λ' and T). Not public API: used only if it imports and
# reproduces ``@`` (the same kernel, so the same results); otherwise ``@``.
_CSR_MATVEC = _load_matvec()


def csr_matvec(a: sp.csr_matrix, x: NDArray[Any]) -> NDArray[Any]:
    """``a @ x`` for a CSR matrix and a contiguous vector of the matrix's dtype (else ``@``).

    Shapes:
        a: (M, N); x: (N,); returns (M,).
    """
    if _CSR_MATVEC is None or x.dtype != a.dtype or x.ndim != 1 or not x.flags.c_contiguous:
        return np.asarray(a @ x)
    y = np.zeros(a.shape[0], a.dtype)
    _CSR_MATVEC(a.shape[0], a.shape[1], a.indptr, a.indices, a.data, x, y)
    return y


@dataclass(frozen=True, slots=True)
class LogPolarConfig:
    """Log-polar grid of the roll/scale partition."""

    n_theta: int = param(192, 'angle samples over 360 deg (roll resolution 360/n_theta deg)',
                         lo=4, hi=4096, read_only=True)
    n_rho: int = param(36, 'log-radius samples from r_min to r_max', lo=2, hi=4096,
                       read_only=True)
    r_min: float = param(4.0, 'innermost ring radius in frame pixels', lo=0.01, hi=1000.0,
                         read_only=True)
    r_max: float = param(0.0, 'outermost ring radius in frame pixels (0: half the image '
                         'diagonal, so the grid covers the whole frame)', lo=0.0, hi=10000.0,
                         read_only=True)
    ring_weight: float = param(0.5, 'exponent a of the ring weights (rho / r_max)^a of the '
                               'log-polar images in the roll/scale updates (0: all rings equal; '
                               '1: by arc length, so the over-sampled centre does not dominate)',
                               lo=0.0, hi=4.0, read_only=True)

    def __post_init__(self) -> None:
        validate(self)
        if self.r_max and self.r_max <= self.r_min:
            raise ConfigError(f'LogPolarConfig.r_max = {self.r_max} must exceed r_min = '
                              f'{self.r_min} (or be 0 for the half-diagonal)')


@dataclass(frozen=True, slots=True)
class Geometry:
    """Sizes and placement of the Cartesian canvas and the log-polar grid."""

    width: int
    height: int
    canvas_width: int
    canvas_height: int
    n_theta: int
    n_rho: int
    r_min: float
    r_max: float
    ring_weight: float = 0.0

    @property
    def offset(self) -> tuple[int, int]:
        """(x, y) of the image's top-left pixel on the canvas."""
        return ((self.canvas_width - self.width) // 2, (self.canvas_height - self.height) // 2)

    @property
    def centre(self) -> tuple[float, float]:
        """Log-polar centre (x, y) in canvas pixels: the image centre."""
        ox, oy = self.offset
        return ox + (self.width - 1) / 2.0, oy + (self.height - 1) / 2.0

    @property
    def d_rho(self) -> float:
        """Log-radius step Δ between rings."""
        return math.log(self.r_max / self.r_min) / (self.n_rho - 1)

    @property
    def n_cart(self) -> int:
        """N_C = canvas pixels."""
        return self.canvas_width * self.canvas_height

    @property
    def n_lp(self) -> int:
        """N_LP = log-polar samples."""
        return self.n_theta * self.n_rho


def make_geometry(width: int, height: int, canvas_width: int, canvas_height: int,
                  lp: LogPolarConfig, canvas_scale: float = 0.0) -> Geometry:
    """Resolve defaults (canvas 0 = image size, or ``canvas_scale`` times it rounded up;
    r_max 0 = half-diagonal) and check sizes.

    Raises:
        ConfigError: if the canvas is smaller than the image.
    """
    def scaled(n: int) -> int:     # (the tolerance keeps 96 * 1.3333333 at 128)
        return max(n, math.ceil(n * canvas_scale - 1e-6)) if canvas_scale > 0.0 else n

    cw = canvas_width or scaled(width)
    ch = canvas_height or scaled(height)
    if cw < width or ch < height:
        raise ConfigError(f'canvas {cw}x{ch} is smaller than the {width}x{height} frame: set '
                          'canvas_width/canvas_height to 0 (= frame size) or larger')
    r_max = lp.r_max or 0.5 * math.hypot(width, height)
    if r_max <= lp.r_min:
        raise ConfigError(f'r_max = {r_max} must exceed r_min = {lp.r_min}')
    return Geometry(width, height, cw, ch, lp.n_theta, lp.n_rho, lp.r_min, r_max,
                    lp.ring_weight)


def lp_radii(g: Geometry) -> NDArray[np.float64]:
    """Ring radii ρ_j in pixels. Shapes: (n_rho,)."""
    return np.asarray(g.r_min * np.exp(np.arange(g.n_rho) * g.d_rho), np.float64)


def ring_weights(g: Geometry) -> NDArray[np.float64]:
    """Ring weights ``(ρ_j / r_max)^a`` (a = ``ring_weight``). Shapes: (n_rho,)."""
    return np.asarray((lp_radii(g) / g.r_max) ** g.ring_weight, np.float64)


def cart_to_lp_matrix(g: Geometry) -> sp.csr_matrix:
    """T: bilinear resampling of the canvas onto the log-polar grid (N_LP x N_C, CSR)."""
    cx, cy = g.centre
    rho = lp_radii(g)
    theta = 2.0 * np.pi * np.arange(g.n_theta) / g.n_theta
    px = (cx + rho[:, None] * np.cos(theta)[None, :]).ravel()
    py = (cy + rho[:, None] * np.sin(theta)[None, :]).ravel()
    x0, y0 = np.floor(px), np.floor(py)
    fx, fy = px - x0, py - y0
    rows, cols, vals = [], [], []
    row = np.arange(g.n_lp)
    for dx, dy, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)),
                      (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        xi, yi = (x0 + dx).astype(np.intp), (y0 + dy).astype(np.intp)
        ok = (xi >= 0) & (xi < g.canvas_width) & (yi >= 0) & (yi < g.canvas_height) & (w > 0)
        rows.append(row[ok])
        cols.append(yi[ok] * g.canvas_width + xi[ok])
        vals.append(w[ok])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(g.n_lp, g.n_cart))


def lp_to_cart_matrix(g: Geometry) -> sp.csr_matrix:
    """T': bilinear resampling of the log-polar grid back onto the canvas (N_C x N_LP, CSR)."""
    cx, cy = g.centre
    yy, xx = np.mgrid[0:g.canvas_height, 0:g.canvas_width]
    dx, dy = (xx - cx).ravel(), (yy - cy).ravel()
    rho = np.hypot(dx, dy)
    theta = np.mod(np.arctan2(dy, dx), 2.0 * np.pi)
    jf = np.log(np.maximum(rho, g.r_min) / g.r_min) / g.d_rho
    kf = theta / (2.0 * np.pi / g.n_theta)
    inside = jf <= (g.n_rho - 1) + 1e-9
    jf = np.minimum(jf, g.n_rho - 1)
    j0, k0 = np.floor(jf), np.floor(kf)
    fj, fk = jf - j0, kf - k0
    rows, cols, vals = [], [], []
    row = np.arange(g.n_cart)
    for dj, dk, w in ((0, 0, (1 - fj) * (1 - fk)), (1, 0, fj * (1 - fk)),
                      (0, 1, (1 - fj) * fk), (1, 1, fj * fk)):
        ji = (j0 + dj).astype(np.intp)
        ki = np.mod(k0 + dk, g.n_theta).astype(np.intp)
        ok = inside & (ji < g.n_rho) & (w > 0)
        rows.append(row[ok])
        cols.append(ji[ok] * g.n_theta + ki[ok])
        vals.append(w[ok])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(g.n_cart, g.n_lp))


class LogPolarTransform:
    """Λ and Λ' for DFT codebooks in the fast FFT form.

    Vectors are 2-D arrays in the frequency domain: Cartesian (H_c, W_c), log-polar
    (n_rho, n_theta). ``Λ x = fft2(T · ifft2(x))``, ``Λ' y = fft2(T' · ifft2(y))``.

    Args:
        g: The grid geometry.
        workers: scipy.fft worker threads (1 for single-thread benchmarks).
    """

    def __init__(self, g: Geometry, *, workers: int = 1) -> None:
        self.g = g
        self.workers = workers
        self.T = cart_to_lp_matrix(g)
        self.Tr = lp_to_cart_matrix(g)
        # Complex copies: scipy would otherwise upcast the real matrix on every product.
        self._Tc = self.T.astype(np.complex128)
        self._Trc = self.Tr.astype(np.complex128)
        self.lp_shape = (g.n_rho, g.n_theta)
        self.cart_shape = (g.canvas_height, g.canvas_width)
        self.weighted = g.ring_weight != 0.0
        self.last_lp_image: NDArray[np.floating] | None = None
        self.w = ring_weights(g)
        wrow = np.repeat(self.w, g.n_theta)
        self._Twc = sp.diags(wrow).tocsr() @ self._Tc if self.weighted else self._Tc

    @functools.cached_property
    def _single(self) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]:
        """T, T' and W T as complex64 (built on first use: the fast engine's spectra are single
        precision)."""
        return (self._Tc.astype(np.complex64), self._Trc.astype(np.complex64),
                self._Twc.astype(np.complex64))

    def lp_image(self, canvas: NDArray[np.floating]) -> NDArray[np.float64]:
        """The log-polar image ``T · canvas``. Shapes: (H_c, W_c) real → (n_rho, n_theta)."""
        x = canvas.ravel().astype(np.float64, copy=False)     # (as @ upcasts float32)
        return csr_matvec(self.T, x).reshape(self.lp_shape)

    def encode_image_lp(self, canvas: NDArray[np.floating]) -> Complex:
        """``Λ s`` for ``s = fft2(canvas)``, computed directly: ``fft2_LP(T · canvas)``.

        Shapes:
            canvas: (H_c, W_c) real; returns (n_rho, n_theta) complex128.
        """
        lp = self.lp_image(canvas)
        self.last_lp_image = lp
        return np.asarray(hfft.fft2(lp, workers=self.workers), np.complex128)

    def weight_image(self, lp: NDArray[np.floating]) -> Complex:
        """``D_w Λ s`` from the log-polar image ``T · canvas`` (one FFT instead of two)."""
        return np.asarray(hfft.fft2(lp * self.w[:, None], workers=self.workers), np.complex128)

    def forward(self, x: Complex) -> Complex:
        """Λ x. Shapes: x (H_c, W_c) → (n_rho, n_theta)."""
        img = hfft.ifft2(x, workers=self.workers).ravel()
        out = hfft.fft2((self._Tc @ img).reshape(self.lp_shape), workers=self.workers,
                        overwrite_x=True)
        return np.asarray(out, np.complex128)

    def forward_weighted(self, x: Complex) -> Complex:
        """Λ_w x = fft2_LP(W T · ifft2_C(x)), W = diag(ring weights). Shapes: as forward;
        complex64 in, complex64 out (else complex128)."""
        img = hfft.ifft2(x, workers=self.workers).ravel()
        if x.dtype == np.complex64:
            return np.asarray(hfft.fft2(csr_matvec(self._single[2], img).reshape(self.lp_shape),
                                        workers=self.workers, overwrite_x=True), np.complex64)
        out = hfft.fft2((self._Twc @ img).reshape(self.lp_shape), workers=self.workers,
                        overwrite_x=True)
        return np.asarray(out, np.complex128)

    def weight(self, y: NDArray[np.complexfloating[Any, Any]]) -> Complex:
        """D_w y = fft2(W · ifft2(y)): ring-weight a log-polar vector. Shapes: (n_rho, n_theta)."""
        if not self.weighted:
            return np.asarray(y, np.complex128)
        img = hfft.ifft2(y, workers=self.workers)
        img *= self.w[:, None]
        return np.asarray(hfft.fft2(img, workers=self.workers, overwrite_x=True),
                          np.complex128)

    def reverse_theta(self, y: Complex) -> Complex:
        """Λ' y from ``y``'s spectrum along θ only (``y = fft_θ(Y)``, not transformed along ρ):
        ``Λ' fft_ρ(y) = fft2_C(T' · ifft_θ(y))``, one 1-D inverse FFT per ring instead of a
        2-D one. ``y`` is overwritten (pass a temporary). complex64 in, complex64 out.
        Shapes: y (n_rho, n_theta) → (H_c, W_c)."""
        tr = self._single[1] if y.dtype == np.complex64 else self._Trc
        img = hfft.ifft(y, axis=1, workers=self.workers, overwrite_x=True).ravel()
        out = hfft.fft2(csr_matvec(tr, img).reshape(self.cart_shape), workers=self.workers,
                        overwrite_x=True)
        return np.asarray(out, y.dtype)

    def forward_theta(self, x: Complex) -> Complex:
        """``fft_θ(T · ifft2_C(x))``: Λ x without its FFT along ρ (a caller that only sums over ρ
        against another θ-spectrum uses Parseval instead). ``x`` is overwritten (pass a
        scratch array). complex64 in, complex64 out. Shapes: as forward."""
        t = self._single[0] if x.dtype == np.complex64 else self._Tc
        img = hfft.ifft2(x, workers=self.workers, overwrite_x=True).ravel()
        out = hfft.fft(csr_matvec(t, img).reshape(self.lp_shape), axis=1, workers=self.workers,
                       overwrite_x=True)
        return np.asarray(out, x.dtype)

    def reverse(self, y: Complex) -> Complex:
        """Λ' y. Shapes: y (n_rho, n_theta) → (H_c, W_c); complex64 in, complex64 out (else
        complex128)."""
        img = hfft.ifft2(y, workers=self.workers).ravel()
        if y.dtype == np.complex64:
            return np.asarray(hfft.fft2(csr_matvec(self._single[1], img).reshape(
                self.cart_shape), workers=self.workers, overwrite_x=True), np.complex64)
        out = hfft.fft2((self._Trc @ img).reshape(self.cart_shape), workers=self.workers,
                        overwrite_x=True)
        return np.asarray(out, np.complex128)


def dense_lambdas(phi_c: NDArray[np.complexfloating], phi_lp: NDArray[np.complexfloating],
                  g: Geometry, *, rcond: float = 1e-6,
                  dtype: type[np.complexfloating] = np.complex128
                  ) -> tuple[NDArray[np.complexfloating], NDArray[np.complexfloating]]:
    """Dense Λ = Φ_LP T Φ_C⁺ and Λ' = Φ_C T' Φ_LP⁺ for any codebooks.

    Args:
        phi_c: Cartesian codebook, column ``x + W_c y`` = h0^x ⊙ v0^y.
        phi_lp: Log-polar codebook, column ``k + n_theta j`` = θ0^k ⊙ ρ0^j.
        g: The grid geometry.
        rcond: Relative cut-off of the pseudo-inverses (regularises random codebooks).
        dtype: Storage type of the results.

    Shapes:
        phi_c: (N, N_C); phi_lp: (N, N_LP); returns (N, N) each.
    """
    T, Tr = cart_to_lp_matrix(g), lp_to_cart_matrix(g)
    pinv_c = np.linalg.pinv(phi_c, rcond=rcond)       # (N_C, N)
    pinv_lp = np.linalg.pinv(phi_lp, rcond=rcond)     # (N_LP, N)
    lam = (phi_lp @ (T @ pinv_c)).astype(dtype)
    lam_r = (phi_c @ (Tr @ pinv_lp)).astype(dtype)
    return lam, lam_r


def dense_ring_weighting(phi_lp: NDArray[np.complexfloating] | None, g: Geometry, *,
                         rcond: float = 1e-6,
                         dtype: type[np.complexfloating] = np.complex128
                         ) -> NDArray[np.complexfloating]:
    """Dense D_w = Φ_LP W Φ_LP⁺ (ring weighting in the vector space); ``phi_lp=None``: DFT.

    Shapes:
        returns (N, N) (N = N_LP for DFT).
    """
    wrow = np.repeat(ring_weights(g), g.n_theta)
    if phi_lp is None:
        nr, nt = g.n_rho, g.n_theta
        eye = np.eye(g.n_lp, dtype=np.complex128).reshape(g.n_lp, nr, nt)
        finv = sfft.ifft2(eye, axes=(1, 2)).reshape(g.n_lp, g.n_lp).T       # F^-1 columns
        tmp = (wrow[:, None] * finv).reshape(nr, nt, g.n_lp)
        return np.asarray(sfft.fft2(tmp, axes=(0, 1)).reshape(g.n_lp, g.n_lp), dtype)
    pinv_lp = np.linalg.pinv(phi_lp, rcond=rcond)
    return np.asarray(phi_lp @ (wrow[:, None] * pinv_lp), dtype)


def dense_lambdas_dft(g: Geometry, *, dtype: type[np.complexfloating] = np.complex128
                      ) -> tuple[NDArray[np.complexfloating], NDArray[np.complexfloating]]:
    """The same dense Λ, Λ' for DFT codebooks, built column by column with batched FFTs.

    Mathematically identical to :func:`dense_lambdas` with 2-D DFT Φ's (a test checks it), but
    O(N² log N) instead of O(N³), so the full 96x72 reference matrices build in seconds.

    Shapes:
        returns (N_LP, N_C) and (N_C, N_LP).
    """
    hc, wc, nr, nt = g.canvas_height, g.canvas_width, g.n_rho, g.n_theta
    T, Tr = cart_to_lp_matrix(g), lp_to_cart_matrix(g)
    # Column n of F_C^-1 is ifft2 of the n-th unit vector; F^-1 is symmetric, so batch rows.
    eye_c = np.eye(g.n_cart, dtype=np.complex128).reshape(g.n_cart, hc, wc)
    finv_c = sfft.ifft2(eye_c, axes=(1, 2)).reshape(g.n_cart, g.n_cart)   # rows = columns
    del eye_c
    tmp = (T @ finv_c.T).reshape(nr, nt, g.n_cart)                          # T F_C^-1
    del finv_c
    lam = sfft.fft2(tmp, axes=(0, 1)).reshape(g.n_lp, g.n_cart).astype(dtype)
    del tmp
    eye_lp = np.eye(g.n_lp, dtype=np.complex128).reshape(g.n_lp, nr, nt)
    finv_lp = sfft.ifft2(eye_lp, axes=(1, 2)).reshape(g.n_lp, g.n_lp)
    del eye_lp
    tmp = (Tr @ finv_lp.T).reshape(hc, wc, g.n_lp)
    del finv_lp
    lam_r = sfft.fft2(tmp, axes=(0, 1)).reshape(g.n_cart, g.n_lp).astype(dtype)
    return lam, lam_r
