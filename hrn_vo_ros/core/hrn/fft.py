"""FFTs of the HRN's hot path: scipy's pocketfft kernels called directly, else ``scipy.fft``.

``scipy.fft``'s public functions reach the pocketfft kernels through uarray backend dispatch
and argument normalisation, a few µs per call. One HRN step makes about 28 FFTs of 96x96,
36x192, 96 and 192 points, where that dispatch measured 12 % of the step (alternating steps in
one process, ``bench/bench_hrn_speed.py`` config). The kernels are the ones the public functions
end in, so results are identical. ``scipy.fft._pocketfft.pypocketfft`` is not public API: it
is used only if it imports and reproduces ``scipy.fft`` on a check at import; otherwise (a
future scipy, another distribution) every function falls back to ``scipy.fft`` — slower, same
results. :data:`BACKEND` says which is in use.

Conventions as ``scipy.fft`` (norm ``'backward'``: forward unnormalised, inverse 1/n). ``fft2``
and friends transform the last two axes. ``overwrite_x=True`` lets a complex input be
overwritten by the result (pass a temporary).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
import scipy.fft as _sfft

Arr = NDArray[Any]

fftfreq = _sfft.fftfreq
rfftfreq = _sfft.rfftfreq


def _load() -> Any:
    """The pocketfft module if it reproduces scipy.fft, else None."""
    try:
        from scipy.fft._pocketfft import pypocketfft as pp
        rng = np.random.default_rng(0)
        for dtype in (np.complex64, np.complex128):
            x = (rng.normal(size=(6, 10)) + 1j * rng.normal(size=(6, 10))).astype(dtype)
            pairs = [(pp.c2c(x, (1,), True, 0, None, 1), _sfft.fft(x, axis=1)),
                     (pp.c2c(x, (0, 1), False, 2, None, 1), _sfft.ifft2(x))]
            for got, want in pairs:
                if got.dtype != want.dtype or not np.allclose(got, want, rtol=1e-5, atol=1e-5):
                    return None
        r = rng.normal(size=(6, 10))
        spec = pp.r2c(r, (0, 1), True, 0, None, 1)
        if (not np.allclose(spec, _sfft.rfft2(r))
                or not np.allclose(pp.c2r(spec, (0, 1), 10, False, 2, None, 1), r)
                or not np.allclose(pp.c2c(r, (1,), True, 0, None, 1), _sfft.fft(r, axis=1))):
            return None
        return pp
    except Exception:          # any failure means: use the public API
        return None


_PP = _load()
BACKEND = 'pocketfft' if _PP is not None else 'scipy.fft'


def _c2c(x: Arr, axes: tuple[int, ...], forward: bool, workers: int, overwrite_x: bool) -> Arr:
    # (the hot path: one HRN step makes about 26 calls, so no more Python than needed here)
    if _PP is None:
        f = {(True, 1): _sfft.fft, (False, 1): _sfft.ifft,
             (True, 2): _sfft.fft2, (False, 2): _sfft.ifft2}[(forward, len(axes))]
        if len(axes) == 1:
            return np.asarray(f(x, axis=axes[0], workers=workers, overwrite_x=overwrite_x))
        return np.asarray(f(x, workers=workers, overwrite_x=overwrite_x))
    kind = x.dtype.kind
    if kind not in 'fc':
        x = x.astype(np.float64)
    out = x if overwrite_x and kind == 'c' and x.flags.writeable else None
    res: Arr = _PP.c2c(x, axes, forward, 0 if forward else 2, out, workers)
    return res


def fft(x: Arr, axis: int = -1, *, workers: int = 1, overwrite_x: bool = False) -> Arr:
    """1-D FFT along ``axis``."""
    x = np.asarray(x)
    return _c2c(x, (axis % x.ndim,), True, workers, overwrite_x)


def ifft(x: Arr, axis: int = -1, *, workers: int = 1, overwrite_x: bool = False) -> Arr:
    """1-D inverse FFT along ``axis``."""
    x = np.asarray(x)
    return _c2c(x, (axis % x.ndim,), False, workers, overwrite_x)


def fft2(x: Arr, *, workers: int = 1, overwrite_x: bool = False) -> Arr:
    """2-D FFT over the last two axes."""
    x = np.asarray(x)
    n = x.ndim
    return _c2c(x, (n - 2, n - 1), True, workers, overwrite_x)


def ifft2(x: Arr, *, workers: int = 1, overwrite_x: bool = False) -> Arr:
    """2-D inverse FFT over the last two axes."""
    x = np.asarray(x)
    n = x.ndim
    return _c2c(x, (n - 2, n - 1), False, workers, overwrite_x)


def rfft2(x: Arr, *, workers: int = 1) -> Arr:
    """2-D FFT of a real 2-D array, non-negative frequencies along the last axis."""
    x = np.asarray(x)
    if _PP is None:
        return np.asarray(_sfft.rfft2(x, workers=workers))
    if x.dtype.kind != 'f':
        x = x.astype(np.float64)
    return np.asarray(_PP.r2c(x, (0, 1), True, 0, None, workers))


def irfft2(x: Arr, shape: tuple[int, int], *, workers: int = 1) -> Arr:
    """Inverse of :func:`rfft2` for a real 2-D array of ``shape``."""
    x = np.asarray(x)
    if _PP is None:
        return np.asarray(_sfft.irfft2(x, s=shape, workers=workers))
    return np.asarray(_PP.c2r(x, (0, 1), int(shape[1]), False, 2, None, workers))
