"""The tracking quality's measures (core/hrn/shared.py): frame-map overlaps, the high-pass
weights and the peak-to-sidelobe ratio, against image-domain and brute-force references."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrn_vo_ros.core.hrn.shared import (
    highpass_weights,
    peak_to_sidelobe,
    population_readout,
    spectral_overlap,
    weighted_overlap,
)


def _images(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    a = (rng.random((24, 32)) < 0.2).astype(np.float64)
    b = np.roll(a, (1, 2), axis=(0, 1)) + 0.5 * (rng.random((24, 32)) < 0.1)
    return a, b


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_overlaps_are_image_correlations_by_parseval(seed: int) -> None:
    """Without DC the spectral overlap is the correlation coefficient of the two images; with
    a real weight it is the cosine of the two filtered images."""
    a, b = _images(seed)
    m, t = np.fft.fft2(a), np.fft.fft2(b)
    da, db = a - a.mean(), b - b.mean()
    pearson = float(np.sum(da * db) / math.sqrt(np.sum(da * da) * np.sum(db * db)))
    assert spectral_overlap(m, t) == pytest.approx(pearson, abs=1e-12)
    w = highpass_weights(24, 32, 3.0)
    fa, fb = np.fft.ifft2(w * m), np.fft.ifft2(w * t)
    cos = float(np.vdot(fa, fb).real / math.sqrt(np.vdot(fa, fa).real * np.vdot(fb, fb).real))
    assert weighted_overlap(m, t, w) == pytest.approx(cos, abs=1e-12)
    assert weighted_overlap(m, t, highpass_weights(24, 32, 0.0)) == pytest.approx(pearson,
                                                                                 abs=1e-12)
    blank = np.fft.fft2(np.full((24, 32), 0.3))            # DC only
    assert spectral_overlap(m, blank) == 0.0 and spectral_overlap(blank, t) == 0.0
    assert weighted_overlap(blank, t, w) == 0.0 and weighted_overlap(m, 0 * t, w) == 0.0


def test_highpass_weights_by_hand() -> None:
    """1 - exp(-|k|^2 / (2 c^2)) in FFT order (the last row is frequency -1); cutoff 0: all
    ones but DC."""
    w = highpass_weights(8, 10, 3.0)
    assert w[0, 0] == 0.0
    assert w[0, 1] == pytest.approx(1.0 - math.exp(-1.0 / 18.0))
    assert w[7, 0] == pytest.approx(1.0 - math.exp(-1.0 / 18.0))          # ky = -1
    assert w[2, 9] == pytest.approx(1.0 - math.exp(-(4.0 + 1.0) / 18.0))  # ky 2, kx -1
    flat = highpass_weights(8, 10, 0.0)
    assert flat[0, 0] == 0.0 and flat.sum() == 79.0


def _psr_reference(mc: np.ndarray, t: np.ndarray, w: np.ndarray, exclude: int) -> float:
    """The definition, written out: the correlation from the frequencies |ky| < H/4 and
    0 <= kx <= W/4 at half resolution, its value at shift 0 against the mean and standard
    deviation outside the (2 exclude + 1)^2 window around shift 0 (circular)."""
    h, wd = t.shape
    h4, w4 = h // 4, wd // 4
    ky = np.fft.fftfreq(h, 1.0 / h).astype(int)
    rows = np.concatenate([np.flatnonzero((ky >= 0) & (ky < h4)),
                           np.flatnonzero((ky < 0) & (ky >= -h4))])
    spec = (t * mc * w)[rows][:, :w4 + 1]
    corr = np.fft.irfft2(spec, s=(2 * h4, 2 * w4))
    dy = np.minimum(np.arange(2 * h4), 2 * h4 - np.arange(2 * h4))
    dx = np.minimum(np.arange(2 * w4), 2 * w4 - np.arange(2 * w4))
    side = ~((dy[:, None] <= exclude) & (dx[None, :] <= exclude))
    return float((corr[0, 0] - corr[side].mean()) / corr[side].std())


@pytest.mark.parametrize('exclude', [1, 2])
def test_peak_to_sidelobe_equals_its_definition(exclude: int) -> None:
    """On a frame that matches the map at the estimate and on one that does not (random), the
    ratio equals the written-out definition; the match stands out, the random one does not."""
    rng = np.random.default_rng(7)
    a = (rng.random((48, 64)) < 0.1).astype(np.float64)
    m = np.fft.fft2(a)
    w = highpass_weights(48, 64, 3.0)
    for frame, high in ((a, True), ((rng.random((48, 64)) < 0.1).astype(np.float64), False)):
        t = np.fft.fft2(frame)
        got = peak_to_sidelobe(np.conj(m), t, w, exclude)
        assert got == pytest.approx(_psr_reference(np.conj(m), t, w, exclude), rel=1e-9)
        assert (got > 8.0) if high else (got < 4.0)
    assert peak_to_sidelobe(np.conj(m), np.zeros_like(m), w, 1) == 0.0


def test_population_readout_by_hand() -> None:
    """Eq. 7 around the peak: weights 1, 3, 1 at entries 2, 3, 4 give index 3 and spread
    sqrt(2/5) (the 2 at entry 6 lies outside the window); at the start of a periodic book the
    window wraps (1 at entry -1, i.e. K - 1, 3 at 0, 1 at 1: index 0), of a bounded one it is
    cut (3 and 1: index 0.25), at the end likewise (6.75); negative weights count as 0, and an
    all-negative window gives the peak's own index."""
    sim = np.array([0.0, -1.0, 1.0, 3.0, 1.0, 0.0, 2.0, 0.0])     # entry 6: outside
    idx, spread, peak = population_readout(sim, 2, False)
    assert (idx, peak) == (pytest.approx(3.0), 3.0)
    assert spread == pytest.approx(math.sqrt(2.0 / 5.0))
    end = np.array([3.0, 1.0, -2.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    assert population_readout(end, 2, True)[0] == pytest.approx(0.0)   # 1 at -1 and at 1
    assert population_readout(end, 2, False)[0] == pytest.approx(0.25)  # cut at 0: 3, 1
    assert population_readout(end[::-1].copy(), 2, False)[0] == pytest.approx(6.75)
    low = np.full(8, -1.0)
    low[5] = -0.5
    assert population_readout(low, 2, False) == (5.0, 0.0, -0.5)
    # a peak across the wrap: 0.5, 1, 1, 0.5 at entries 18, 19, 0, 1 = offsets -2..1: index
    # -0.5, variance (0.5 1.5² + 1 0.5² + 1 0.5² + 0.5 1.5²) / 3
    straddle = np.zeros(20)
    straddle[[18, 19, 0, 1]] = [0.5, 1.0, 1.0, 0.5]
    idx, spread, peak = population_readout(straddle, 5, True)
    assert (idx, peak) == (pytest.approx(-0.5), 1.0)
    assert spread == pytest.approx(math.sqrt((0.5 * 2.25 * 2 + 1.0 * 0.25 * 2) / 3.0))
