"""FPE codebooks: DFT = FFT, centred fractional powers are band-limited shifts, random seeds."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.hrn import fhrr
from hrn_vo_ros.errors import ConfigError


def test_dft_grid_codebook_is_the_2d_fft(rng: np.random.Generator) -> None:
    w, h = 12, 8
    phx = np.broadcast_to(fhrr.dft_phases(w)[None, :], (h, w)).ravel()
    phy = np.broadcast_to(fhrr.dft_phases(h)[:, None], (h, w)).ravel()
    phi = fhrr.grid_codebook(phx, phy, w, h)
    img = rng.random((h, w))
    np.testing.assert_allclose(phi @ img.ravel(), np.fft.fft2(img).ravel(), atol=1e-10)
    # Integer-shift codebook vectors are orthogonal: X† X = N I.
    np.testing.assert_allclose(phi.conj().T @ phi, w * h * np.eye(w * h), atol=1e-9)


def test_fractional_power_is_a_band_limited_subpixel_shift() -> None:
    n = 64
    x = np.arange(n)
    sig = np.exp(-0.5 * ((x - 30) / 3.0) ** 2)            # smooth bump at 30
    shifted = np.fft.ifft(np.fft.fft(sig) * fhrr.power(fhrr.dft_phases(n), 2.5))
    assert np.abs(shifted.imag).max() < 1e-3               # centred: stays (almost) real
    np.testing.assert_allclose(np.dot(x, shifted.real) / shifted.real.sum(), 32.5, atol=1e-6)
    # Uncentred frequencies 0..n-1 would not: the result is far from real.
    bad = np.fft.ifft(np.fft.fft(sig) * np.exp(-2j * np.pi * np.arange(n) * 2.5 / n))
    assert np.abs(bad.imag).max() > 0.1


def test_random_seeds_are_seeded_looping_and_quasi_orthogonal() -> None:
    a = fhrr.random_phases(3072, np.random.default_rng(7))
    b = fhrr.random_phases(3072, np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
    loop = fhrr.random_phases(3072, np.random.default_rng(1), period=96)
    np.testing.assert_allclose(fhrr.power(loop, 96), 1.0, atol=1e-9)
    x = fhrr.codebook(a, np.arange(10.0))
    gram = np.abs(x.conj().T @ x) / 3072
    assert np.abs(gram - np.eye(10)).max() < 0.1
    # Sinc kernel: similarity at half a step is ~ sinc(0.5) = 0.64.
    half = np.real(np.vdot(fhrr.power(a, 0.0), fhrr.power(a, 0.5))) / 3072
    assert abs(half - np.sinc(0.5)) < 0.05


def test_phasor_projection_and_errors() -> None:
    u = np.array([3 + 4j, 0j, -2j])
    np.testing.assert_allclose(fhrr.phasor(u), [0.6 + 0.8j, 0, -1j])
    with pytest.raises(ConfigError):
        fhrr.dft_phases(0)
    with pytest.raises(ConfigError):
        fhrr.random_phases(10, np.random.default_rng(0), period=0)
