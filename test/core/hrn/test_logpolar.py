"""Log-polar transforms: rotation = θ shift, zoom = ρ shift, fast Λ = dense Λ."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from hrn_vo_ros.core.hrn import fhrr
from hrn_vo_ros.core.hrn.logpolar import (
    cart_to_lp_matrix,
    dense_lambdas,
    dense_lambdas_dft,
    LogPolarConfig,
    LogPolarTransform,
    lp_radii,
    lp_to_cart_matrix,
    make_geometry,
    ring_weights,
)
from hrn_vo_ros.errors import ConfigError


def blob_image(w: int, h: int, angle: float, scale: float = 1.0) -> np.ndarray:
    """An off-centre Gaussian blob at polar angle ``angle`` (rad) about the image centre."""
    cx, cy = (w - 1) / 2, (h - 1) / 2
    yy, xx = np.mgrid[0:h, 0:w]
    bx, by = cx + 15 * scale * np.cos(angle), cy + 15 * scale * np.sin(angle)
    return np.exp(-0.5 * ((xx - bx) ** 2 + (yy - by) ** 2) / (2.0 * scale) ** 2)


def test_rotation_and_zoom_become_shifts_of_the_log_polar_image() -> None:
    g = make_geometry(64, 48, 0, 0, LogPolarConfig(n_theta=64, n_rho=48))
    T = cart_to_lp_matrix(g)
    a = (T @ blob_image(64, 48, 0.3).ravel()).reshape(48, 64)
    b = (T @ blob_image(64, 48, 0.3 + 2 * np.pi * 5 / 64).ravel()).reshape(48, 64)
    np.testing.assert_allclose(np.roll(a, 5, axis=1), b, atol=0.05 * a.max())
    k = np.exp(3 * g.d_rho)
    c = (T @ blob_image(64, 48, 0.3, k).ravel()).reshape(48, 64)
    ca, cc = ndimage.center_of_mass(a), ndimage.center_of_mass(c)
    assert abs((cc[0] - ca[0]) - 3) < 0.3 and abs(cc[1] - ca[1]) < 0.3


def test_reverse_resampling_recovers_the_image_inside_r_max() -> None:
    g = make_geometry(64, 48, 0, 0, LogPolarConfig(n_theta=128, n_rho=64, r_min=1.0, r_max=23))
    img = ndimage.gaussian_filter(np.random.default_rng(0).random((48, 64)), 2.0)
    back = (lp_to_cart_matrix(g) @ (cart_to_lp_matrix(g) @ img.ravel())).reshape(48, 64)
    yy, xx = np.mgrid[0:48, 0:64]
    inner = np.hypot(xx - 31.5, yy - 23.5) < 20
    assert np.abs(back - img)[inner].max() < 0.05 * img.max()
    assert np.all(back[np.hypot(xx - 31.5, yy - 23.5) > 23.5] == 0)


def test_fast_lambda_equals_dense_lambda_dft_and_generic(rng: np.random.Generator) -> None:
    g = make_geometry(20, 14, 24, 16, LogPolarConfig(n_theta=24, n_rho=12))
    lt = LogPolarTransform(g)
    lam, lam_r = dense_lambdas_dft(g)

    def full(ph: np.ndarray, other: int, axis: int) -> np.ndarray:
        shape = (other, len(ph)) if axis == 1 else (len(ph), other)
        return np.broadcast_to(ph[None, :] if axis == 1 else ph[:, None], shape).ravel()

    phi_c = fhrr.grid_codebook(full(fhrr.dft_phases(24), 16, 1), full(fhrr.dft_phases(16), 24, 0),
                               24, 16)
    phi_lp = fhrr.grid_codebook(full(fhrr.dft_phases(24), 12, 1),
                                full(fhrr.dft_phases(12), 24, 0), 24, 12)
    lam2, lam_r2 = dense_lambdas(phi_c, phi_lp, g)
    np.testing.assert_allclose(lam, lam2, atol=1e-10)
    np.testing.assert_allclose(lam_r, lam_r2, atol=1e-10)
    x = rng.normal(size=(16, 24)) + 1j * rng.normal(size=(16, 24))
    np.testing.assert_allclose(lt.forward(x).ravel(), lam @ x.ravel(), atol=1e-9)
    y = rng.normal(size=(12, 24)) + 1j * rng.normal(size=(12, 24))
    np.testing.assert_allclose(lt.reverse(y).ravel(), lam_r @ y.ravel(), atol=1e-9)
    img = rng.random((16, 24))
    np.testing.assert_allclose(lt.encode_image_lp(img), lt.forward(np.fft.fft2(img)),
                               atol=1e-9)


def test_theta_only_forms_match_the_2d_transforms(rng: np.random.Generator) -> None:
    """The direct form of the fast engine: Λ' from a θ-spectrum, and Parseval along ρ."""
    g = make_geometry(20, 14, 24, 16, LogPolarConfig(n_theta=24, n_rho=12, ring_weight=0.5))
    lt = LogPolarTransform(g)
    y = rng.normal(size=(12, 24)) + 1j * rng.normal(size=(12, 24))   # a θ-spectrum
    np.testing.assert_allclose(lt.reverse_theta(y.copy()), lt.reverse(np.fft.fft(y, axis=0)),
                               atol=1e-9)
    x = rng.normal(size=(16, 24)) + 1j * rng.normal(size=(16, 24))
    img = rng.random((16, 24))
    s_theta = np.fft.fft(lt.lp_image(img), axis=1)
    # Σ_kρ (D_w S) ⊙ (Λ_w x)* = n_ρ Σ_ρ w² S_θ ⊙ fft_θ(T ifft2 x)*
    want = (lt.weight(lt.encode_image_lp(img)) * lt.forward_weighted(x).conj()).sum(axis=0)
    got = (12 * lt.w[:, None] ** 2 * s_theta * lt.forward_theta(x.copy()).conj()).sum(axis=0)
    np.testing.assert_allclose(got, want, atol=1e-8 * np.abs(want).max())


def test_geometry_errors() -> None:
    with pytest.raises(ConfigError, match='smaller than'):
        make_geometry(96, 72, 64, 72, LogPolarConfig())
    with pytest.raises(ConfigError, match='r_max'):
        LogPolarConfig(r_min=5.0, r_max=4.0)
    g = make_geometry(96, 72, 0, 0, LogPolarConfig())
    assert g.r_max == pytest.approx(60.0) and g.centre == (47.5, 35.5)


@pytest.mark.parametrize('frame, sizes, scale, canvas', [
    ((96, 72), (0, 0), 4 / 3, (128, 96)),        # live.yaml on a DAVIS240C at 2.5
    ((96, 72), (0, 0), 1.3333333, (128, 96)),    # (as written in the YAML)
    ((256, 192), (0, 0), 4 / 3, (342, 256)),     # a 640x480 sensor: ceil(341.33) = 342
    ((139, 104), (0, 0), 1.5, (209, 156)),       # DAVIS346 at 2.5: ceil(208.5)
    ((96, 72), (0, 0), 0.0, (96, 72)),           # off: the frame size
    ((96, 72), (0, 0), 0.5, (96, 72)),           # never smaller than the frame
    ((96, 72), (100, 0), 4 / 3, (100, 96)),      # a given width wins, the height scales
])
def test_canvas_scale_sizes_the_canvas_from_the_frame(
        frame: tuple[int, int], sizes: tuple[int, int], scale: float,
        canvas: tuple[int, int]) -> None:
    g = make_geometry(*frame, *sizes, LogPolarConfig(), scale)
    assert (g.canvas_width, g.canvas_height) == canvas


def test_the_grid_and_both_resamplings_by_hand() -> None:
    """96x72 frame on a 128x96 canvas, 192 x 36 samples from r_min 4 to the half-diagonal
    60: offset (16, 12), centre (63.5, 47.5), rings 4 e^(j ln(15) / 35); bilinear resampling
    reproduces a linear ramp exactly, so T of the canvas's x and y coordinates gives each
    sample's position, and T' of the ring and angle indices gives ln(rho / 4) / step and
    theta / (2 pi / 192) at every canvas pixel between the inner and outer ring (away from the
    seam at 2 pi); ring weights (rho / 60)^0.5."""
    g = make_geometry(96, 72, 128, 96, LogPolarConfig(ring_weight=0.5))
    assert g.offset == (16, 12) and g.centre == (63.5, 47.5) and g.r_max == 60.0
    assert g.d_rho == pytest.approx(math.log(15.0) / 35)
    rho = lp_radii(g)
    assert rho[0] == pytest.approx(4.0) and rho[-1] == pytest.approx(60.0)
    assert ring_weights(g) == pytest.approx(np.sqrt(rho / 60.0))
    yy, xx = np.mgrid[0:96, 0:128].astype(np.float64)
    T = cart_to_lp_matrix(g)
    theta = 2.0 * np.pi * np.arange(192) / 192
    px = 63.5 + rho[:, None] * np.cos(theta)[None, :]
    py = 47.5 + rho[:, None] * np.sin(theta)[None, :]
    inner = (px >= 0) & (px <= 126) & (py >= 0) & (py <= 94)    # all four taps on the canvas
    assert inner.mean() > 0.8
    np.testing.assert_allclose((T @ xx.ravel()).reshape(36, 192)[inner], px[inner], atol=1e-9)
    np.testing.assert_allclose((T @ yy.ravel()).reshape(36, 192)[inner], py[inner], atol=1e-9)
    ring = np.repeat(np.arange(36, dtype=np.float64), 192)
    r = np.hypot(xx - 63.5, yy - 47.5).ravel()
    band = (r >= 4.0) & (r <= 60.0)
    Tr = lp_to_cart_matrix(g)
    np.testing.assert_allclose((Tr @ ring)[band], np.log(r[band] / 4.0) / g.d_rho, atol=1e-9)
    angle = np.tile(np.arange(192, dtype=np.float64), 36)     # the angle index, k
    kf = np.mod(np.arctan2(yy - 47.5, xx - 63.5), 2.0 * np.pi).ravel() / (2.0 * np.pi / 192)
    away = band & (kf < 191.0)                                # not across the 2 pi seam
    np.testing.assert_allclose((Tr @ angle)[away], kf[away], atol=1e-9)
