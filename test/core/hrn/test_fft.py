"""core/fft.py: the hot-path FFTs equal numpy's, on the direct pocketfft path and the fallback."""

from __future__ import annotations

import types

import numpy as np
import pytest

from hrn_vo_ros.core.hrn import fft as hfft


@pytest.fixture(params=['direct', 'fallback'])
def backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    if request.param == 'fallback':
        monkeypatch.setattr(hfft, '_PP', None)
    elif hfft._PP is None:
        pytest.skip("scipy's pocketfft module is not usable here (the fallback is tested)")
    return str(request.param)


@pytest.mark.parametrize('dtype', [np.complex64, np.complex128, np.float32, np.float64])
def test_transforms_equal_numpy(backend: str, dtype: type) -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(12, 18)) + (1j * rng.normal(size=(12, 18)) if dtype in (
        np.complex64, np.complex128) else 0.0)
    x = x.astype(dtype)
    tol = 1e-4 if dtype in (np.complex64, np.float32) else 1e-10
    for got, want in [(hfft.fft(x, axis=1), np.fft.fft(x, axis=1)),
                      (hfft.fft(x, axis=0), np.fft.fft(x, axis=0)),
                      (hfft.ifft(x, axis=1), np.fft.ifft(x, axis=1)),
                      (hfft.fft2(x), np.fft.fft2(x)), (hfft.ifft2(x), np.fft.ifft2(x))]:
        np.testing.assert_allclose(got, want, rtol=tol, atol=tol * np.abs(want).max())
        single = dtype in (np.complex64, np.float32)
        assert got.dtype == (np.complex64 if single else np.complex128)
    assert hfft.fft(x[0]).shape == (18,)


def test_real_pair_and_overwrite(backend: str) -> None:
    rng = np.random.default_rng(2)
    r = rng.normal(size=(16, 10))
    x = rng.normal(size=(8, 6)) + 1j * rng.normal(size=(8, 6))
    spec = hfft.rfft2(r)
    np.testing.assert_allclose(spec, np.fft.rfft2(r), atol=1e-10)
    np.testing.assert_allclose(hfft.irfft2(spec * 2.0, (16, 10)), 2.0 * r, atol=1e-10)
    frame = (r > 0).astype(np.uint8)                          # an event frame as it comes
    np.testing.assert_allclose(hfft.rfft2(frame), np.fft.rfft2(frame), atol=1e-10)
    np.testing.assert_allclose(hfft.ifft(x[0]), np.fft.ifft(x[0]), atol=1e-10)  # default axis
    want = np.fft.fft2(x)
    tmp = x.copy()
    np.testing.assert_allclose(hfft.fft2(tmp, overwrite_x=True), want, atol=1e-10)
    before = x.copy()
    hfft.fft2(x)
    hfft.ifft(x, axis=0)
    np.testing.assert_array_equal(x, before)                  # without overwrite_x: untouched


def test_a_module_that_disagrees_with_scipy_is_not_used(monkeypatch: pytest.MonkeyPatch) -> None:
    """The import-time check falls back when the private kernels do not reproduce scipy.fft."""
    import scipy.fft

    wrong = types.SimpleNamespace(fft=lambda x, axis=-1: 2.0 * scipy.fft.fft(x, axis=axis),
                                  ifft2=scipy.fft.ifft2, rfft2=scipy.fft.rfft2)
    monkeypatch.setattr(hfft, '_sfft', wrong)
    assert hfft._load() is None
    monkeypatch.undo()
    assert (hfft._load() is None) == (hfft.BACKEND == 'scipy.fft')
