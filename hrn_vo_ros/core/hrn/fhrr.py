"""FHRR vectors and fractional power encoding (FPE) codebooks (``docs/model.md``).

A seed is a unit-phasor vector ``z0 = exp(i φ)``; its (fractional) power is ``z0^a = exp(i a φ)``;
binding is the elementwise product, unbinding the conjugate, bundling the sum.

* **DFT seeds** (``dft_seed(n)``): ``φ_k = -2π k / n`` with the *centred* integer frequencies
  ``k ∈ {-n/2, …, n/2-1}`` stored in FFT order (``np.fft.fftfreq(n) * n``). Integer powers equal
  the plain DFT; fractional powers are band-limited sub-pixel shifts, and ``z0^n = 1`` (toroidal).
  A 2-D DFT codebook ``h0^x ⊙ v0^y`` over a ``W x H`` grid is the 2-D DFT matrix: ``Φ I = fft2(I)``
  with the vector laid out as a (H, W) array, row-major.
* **Random seeds** (``random_seed(n, rng)``): phases uniform in (-π, π] (sinc kernel), or drawn
  from the L-th roots of unity (``period=L``) so that ``z0^L = 1`` (needed for the roll axis).

Codebook matrices have one column per entry: ``X[:, j] = z0^{a_j}``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.errors import ConfigError

Complex = NDArray[np.complex128]
Real = NDArray[np.float64]


def dft_phases(n: int) -> Real:
    """Phases of the centred DFT seed of length ``n`` (FFT element order).

    Shapes:
        returns (n,) float64: ``-2π k/n`` with k = fftfreq(n)*n.
    """
    if n < 1:
        raise ConfigError(f'a DFT seed needs length >= 1, got {n}')
    return np.asarray(-2.0 * np.pi * np.fft.fftfreq(n), np.float64)


def random_phases(n: int, rng: np.random.Generator, *, period: int | None = None) -> Real:
    """Phases of a random FPE seed: uniform in (-π, π], or multiples of 2π/period.

    Shapes:
        returns (n,) float64.
    """
    if n < 1:
        raise ConfigError(f'a random seed needs length >= 1, got {n}')
    if period is None:
        return rng.uniform(-np.pi, np.pi, n)
    if period < 1:
        raise ConfigError(f'the period of a looping seed must be >= 1, got {period}')
    return 2.0 * np.pi * rng.integers(0, period, n) / period


def power(phases: Real, a: float | Real) -> Complex:
    """``z0^a`` for the seed with ``phases`` (``a`` scalar, or (K,) for a codebook (n, K))."""
    a_arr = np.asarray(a, dtype=np.float64)
    if a_arr.ndim == 0:
        return np.asarray(np.exp(1j * phases * float(a_arr)), np.complex128)
    return np.asarray(np.exp(1j * np.outer(phases, a_arr)), np.complex128)


def codebook(phases: Real, values: Real) -> Complex:
    """Codebook matrix with columns ``z0^{values[j]}``.

    Shapes:
        phases: (n,); values: (K,); returns (n, K) complex128.
    """
    return power(phases, np.asarray(values, dtype=np.float64))


def grid_codebook(phases_x: Real, phases_y: Real, width: int, height: int) -> Complex:
    """2-D FPE codebook Φ with column ``x + W y`` = ``h0^x ⊙ v0^y`` (image I (H, W) row-major).

    Shapes:
        phases_x, phases_y: (N,) each (the full vector's phases along each axis);
        returns (N, W*H) complex128.
    """
    hx = codebook(phases_x, np.arange(width, dtype=np.float64))      # (N, W)
    vy = codebook(phases_y, np.arange(height, dtype=np.float64))     # (N, H)
    return (vy[:, :, None] * hx[:, None, :]).reshape(len(phases_x), height * width)


def phasor(u: Complex, eps: float = 1e-30) -> Complex:
    """The phasor projection f(u) = u / |u| elementwise (0 stays 0)."""
    mag = np.abs(u)
    return u / np.maximum(mag, eps)


def random_phasor(n: int, rng: np.random.Generator) -> Complex:
    """A random unit-phasor vector (a resonator state's initial value)."""
    return np.asarray(np.exp(1j * rng.uniform(-np.pi, np.pi, n)), np.complex128)
