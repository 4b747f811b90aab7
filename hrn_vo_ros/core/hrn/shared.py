"""Pieces shared by the engines, the network and the spiking backend.

The state update (:func:`state_gamma`, :func:`blend_state`), the map weight and its start
(:func:`map_mu1`, :func:`map_block`, :func:`map_block_ns`), the cleanup nonlinearity p
(:func:`cleanup_weights`), the 1-D FPE factor codebooks (:class:`FactorCodebook`,
:func:`factor_codebooks`), the readout (:func:`normalised_similarity`,
:func:`population_readout`, :func:`refine_kernel`, :func:`refine_exponent`) and the array type
names. The equations are in ``docs/model.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.hrn import fft as hfft
from hrn_vo_ros.core.hrn import fhrr
from hrn_vo_ros.core.hrn.config import CleanupConfig, ResonatorConfig
from hrn_vo_ros.core.hrn.logpolar import Geometry

Complex = NDArray[np.complex128]
Real = NDArray[np.float64]
Floats = NDArray[np.floating[Any]]   # the placed canvas: float32 in the fast direct form
Spectrum = NDArray[np.complexfloating[Any, Any]]   # complex64 or complex128 (the fast engine)
_Arr = TypeVar('_Arr', bound=Spectrum)


# --------------------------------------------------------------------------------------------
# The state update


def state_gamma(cfg: ResonatorConfig) -> float:
    """The state update speed γ in use: ``imu.gamma`` while the IMU prediction is on (if set),
    ``cleanup.gamma`` otherwise."""
    if cfg.imu.enabled and cfg.imu.gamma > 0.0:
        return cfg.imu.gamma
    return cfg.cleanup.gamma


def map_block(cfg: ResonatorConfig) -> int:
    """Resonator iterations of a new map without map updates in use: ``imu.block_iterations``
    while the IMU prediction is on (if set, >= 0), ``map.block_iterations`` otherwise."""
    if cfg.imu.enabled and cfg.imu.block_iterations >= 0:
        return cfg.imu.block_iterations
    return cfg.map.block_iterations


def map_block_ns(cfg: ResonatorConfig) -> int:
    """Longest time of a new map without map updates (ns; 0: no bound): ``imu.block_s`` while
    the IMU prediction is on. The block ends with ``map_block`` iterations or this time,
    whichever comes first."""
    return round(cfg.imu.block_s * 1e9) if cfg.imu.enabled else 0


def map_mu1(cfg: ResonatorConfig) -> float:
    """The map's weight of its previous value μ1 in use: ``imu.mu1`` while the IMU prediction
    is on (if set), ``map.mu1`` otherwise."""
    if cfg.imu.enabled and cfg.imu.mu1 > 0.0:
        return cfg.imu.mu1
    return cfg.map.mu1


def blend_state(x: Spectrum, cleaned: _Arr, gamma: float) -> _Arr:
    """The state update x̂ ← (1-γ) x̂ + γ C_X(·), in place of ``cleaned``; rows: (n,) or (k, n).

    A blank cleanup (all zero: its input carried nothing, e.g. an empty warped frame) leaves the
    state as it was instead of shrinking it by (1-γ): two blank iterations took a state to 1 %
    and a zero h and v are a fixed point of the resonator (each factor's input is unbound with
    the other's state), so one blank stretch used to freeze the network for good.
    """
    rows = cleaned if cleaned.ndim == 2 else cleaned[None, :]
    # index 0 is Σp (> 0) for cleanups of complete DFT books, so the full test rarely runs
    blank = [i for i in range(rows.shape[0]) if rows[i, 0] == 0 and not rows[i].any()]
    np.multiply(cleaned, gamma, out=cleaned)
    np.add(cleaned, (1 - gamma) * x, out=cleaned)
    for i in blank:
        rows[i] = x[i] if cleaned.ndim == 2 else x
    return cleaned


# --------------------------------------------------------------------------------------------
# Cleanup and codebooks


def cleanup_weights(c: Real, cfg: CleanupConfig, bound: float = 0.0) -> Real:
    """The cleanup nonlinearity p applied to the similarities ``c = Re(X† u)``.

    ``identity``: c; ``relu``: max(c, 0); ``relu_k``: max(c, 0)^k; ``exp``:
    exp(β (c / max|c| - 1)). The phasor projection after ``X p(c)`` makes all of them invariant
    to a positive scale of c, so no normalisation of u is needed.

    Args:
        c: Similarities.
        cfg: The cleanup settings.
        bound: An upper bound of |c| (``|x_j| |u|``); similarities below ``1e-9 * bound`` are
            rounding noise and count as 0 (so a blank input gives p = 0, not amplified noise).

    Shapes:
        c: (K,); returns (K,).
    """
    mag = np.abs(c)
    top = float(mag.max()) if mag.size else 0.0
    if bound > 0.0:
        if top < 1e-9 * bound:
            return np.zeros_like(c)
        small = mag < 1e-9 * bound
        if small.any():
            c = np.where(small, 0.0, c)
    kind = cfg.nonlinearity
    if kind == 'identity':
        return c
    if kind == 'relu':
        return np.maximum(c, 0.0)
    if kind == 'relu_k':
        return np.maximum(c, 0.0) ** cfg.k
    if top <= 0.0:
        return np.zeros_like(c)
    y = c * (cfg.beta / top)
    y -= cfg.beta
    return np.exp(y, out=y)


def centred_mod(x: Any, period: float) -> Any:
    """``x`` wrapped into ``[-period/2, period/2)`` (scalars or arrays)."""
    return (x + 0.5 * period) % period - 0.5 * period


@dataclass(frozen=True, slots=True)
class FactorCodebook:
    """A 1-D FPE codebook along one axis: entries ``seed^{values[j]}``.

    Attributes:
        name: Factor name (h, v, r, z).
        phases: Seed phases along the axis (the factor's frequency axis in the fast path).
        values: Exponent of each entry (index units: pixels, angle samples, ring shifts).
        period: The codebook wraps after this many index units (None: not periodic).
        unit: Physical size of one index unit (pixel 1, 2π/n_θ rad, Δρ).
        sign: Output sign: physical value = sign · unit · index.
    """

    name: str
    phases: Real
    values: Real
    period: float | None
    unit: float
    sign: float

    def wrap(self, index: float) -> float:
        """An exponent (index units) wrapped into the codebook's period, if it has one."""
        return index if self.period is None else float(centred_mod(index, self.period))

    @property
    def matrix(self) -> Complex:
        """(n, K) codebook matrix."""
        return fhrr.codebook(self.phases, self.values)


def factor_codebooks(cfg: ResonatorConfig, g: Geometry) -> dict[str, FactorCodebook]:
    """The 1-D DFT factor codebooks of the fast path (also the dense DFT path's factors)."""
    def centred(n: int) -> Real:      # entries -n/2 .. n/2-1 (shifts both ways)
        return np.arange(n, dtype=float) - n // 2

    books = {
        'h': FactorCodebook('h', fhrr.dft_phases(g.canvas_width), centred(g.canvas_width),
                            float(g.canvas_width), 1.0, -1.0),
        'v': FactorCodebook('v', fhrr.dft_phases(g.canvas_height), centred(g.canvas_height),
                            float(g.canvas_height), 1.0, -1.0),
        'r': FactorCodebook('r', fhrr.dft_phases(g.n_theta), centred(g.n_theta),
                            float(g.n_theta), 2.0 * math.pi / g.n_theta, -1.0),
    }
    if cfg.scale.enabled:
        top = cfg.scale.max_log_scale / g.d_rho
        books['z'] = FactorCodebook('z', fhrr.dft_phases(g.n_rho),
                                    np.linspace(-top, top, cfg.scale.entries), None, g.d_rho, 1.0)
    return books


# --------------------------------------------------------------------------------------------
# Readout


def normalised_similarity(c: Complex, x: Complex, col_norm: float) -> Real:
    """``Re c / (col_norm |x|)``: the decoded similarities ``c = X† x`` of a state ``x``,
    normalised by the codebook column norm and the state norm (0 for a zero state)."""
    nx = float(np.linalg.norm(x))
    if nx == 0.0:
        return np.zeros(c.shape[0])
    return np.real(c) / (col_norm * nx)


def spectral_overlap(m: Spectrum, t: Spectrum) -> float:
    """``Re<m, t> / (|m| |t|)`` of two canvas spectra without their DC terms (element
    ``[0, 0]``), in [-1, 1]; 0 if either is blank. Shapes: m, t (H_c, W_c) or (N,)."""
    m0, t0 = complex(m.flat[0]), complex(t.flat[0])
    num = float(np.vdot(m, t).real) - (m0.conjugate() * t0).real
    nm = float(np.vdot(m, m).real) - abs(m0) ** 2
    nt = float(np.vdot(t, t).real) - abs(t0) ** 2
    if nm <= 0.0 or nt <= 0.0:
        return 0.0
    return num / math.sqrt(nm * nt)


def highpass_weights(height: int, width: int, cutoff: float) -> Real:
    """``1 - exp(-|k|² / (2 cutoff²))`` over the canvas spectrum (k in frequency bins, FFT
    order): 0 at DC, about 1 beyond ``2 cutoff`` bins. Shapes: returns (height, width)."""
    ky = np.fft.fftfreq(height) * height
    kx = np.fft.fftfreq(width) * width
    k2 = ky[:, None] ** 2 + kx[None, :] ** 2
    if cutoff <= 0.0:
        w = np.ones((height, width))
        w[0, 0] = 0.0
        return w
    return np.asarray(1.0 - np.exp(-k2 / (2.0 * cutoff ** 2)), np.float64)


def weighted_overlap(m: Spectrum, t: Spectrum, w: Floats) -> float:
    """``Re<w m, w t> / (|w m| |w t|)`` in [-1, 1] (``w`` real, 0 at DC: the frame's support
    window and DC carry no pose information); 0 if either is blank."""
    wm, wt = m * w, t * w
    nm = float(np.vdot(wm, wm).real)
    nt = float(np.vdot(wt, wt).real)
    if nm <= 0.0 or nt <= 0.0:
        return 0.0
    return float(np.vdot(wm, wt).real) / math.sqrt(nm * nt)


#: Half width (in the correlation's half-resolution pixels) of the window around the peak
#: that the sidelobes leave out: the encoding kernel (0.7 px) and the map's blur widen the peak
#: to about two canvas pixels.
PSR_EXCLUDE = 1


def peak_to_sidelobe(mc: Spectrum, t: Spectrum, w: Floats, exclude: int) -> float:
    """Peak-to-sidelobe ratio of the frame-map cross-correlation at the estimate.

    ``c`` is the high-passed correlation of the frame (moved into the map at the estimate,
    ``t``) with the map over every shift of the canvas, from the lower half of the frequencies
    in each axis (``irfft2`` of the cropped ``w t m̂*``: the correlation at half resolution,
    a quarter of the work; the 0.7 px encoding kernel leaves little above). Its value at shift
    0 against the mean and standard deviation of ``c`` outside the ``(2 exclude + 1)²`` window
    around 0: ``(c[0, 0] - mean) / std``. A frame that matches the map only at its estimate
    gives a high ratio; one that matches it nowhere in particular (noise, a texture finer than
    the frame's pixels, a map learned at wrong poses) gives about what chance gives.

    Args:
        mc: The conjugate map spectrum ``m̂*`` (canvas, full FFT order).
        t: The frame's target spectrum, same shape.
        w: Real spectral weight (the overlap's high-pass), same shape.
        exclude: Half width of the window around shift 0 left out of the sidelobes.

    Returns:
        The ratio; 0 for a blank frame or map.
    """
    h, wd = t.shape
    h4, w4 = h // 4, wd // 4
    lo, hi = np.s_[:h4, :w4 + 1], np.s_[h - h4:, :w4 + 1]
    c = np.concatenate((t[lo] * mc[lo] * w[lo], t[hi] * mc[hi] * w[hi]))
    corr = np.asarray(hfft.irfft2(c, (2 * h4, 2 * w4)), np.float64)
    e = exclude + 1
    win = [corr[:e, :e], corr[:e, -exclude:], corr[-exclude:, :e], corr[-exclude:, -exclude:]]
    n = corr.size - sum(x.size for x in win)
    total = float(corr.sum()) - sum(float(x.sum()) for x in win)
    sq = float(np.vdot(corr, corr)) - sum(float(np.vdot(x, x)) for x in win)
    mean = total / n
    var = sq / n - mean * mean
    if var <= 0.0 or not math.isfinite(var):
        return 0.0
    return float((corr[0, 0] - mean) / math.sqrt(var))


def population_readout(sim: Real, half_window: int, circular: bool
                       ) -> tuple[float, float, float]:
    """Population vector around the peak (paper Eq. 7), negative weights clipped to 0.

    Args:
        sim: Readout similarities over codebook entries.
        half_window: Neighbours on each side of the peak.
        circular: Wrap the window around the ends (periodic codebooks); the returned index is
            then not wrapped (it may lie just outside [0, K)).

    Returns:
        ``(index, spread, peak)``: fractional entry index, weighted standard deviation of the
        index in the window, and the peak similarity.

    Shapes:
        sim: (K,).
    """
    n = sim.shape[0]
    k = int(sim.argmax())
    idx = np.arange(k - half_window, k + half_window + 1)
    if circular:
        w = sim.take(idx, mode='wrap')          # sim[idx mod n]
    else:
        idx = idx[(idx >= 0) & (idx < n)]
        w = sim[idx]
    np.maximum(w, 0.0, out=w)                   # (w is a copy)
    total = float(w.sum())
    if total <= 0.0:
        return float(k), 0.0, float(sim[k])
    mean = float(np.dot(w, idx) / total)
    spread = math.sqrt(max(float(np.dot(w, (idx - mean) ** 2) / total), 0.0))
    return mean, spread, float(sim[k])


_REFINE_GRID = np.linspace(-1.0, 1.0, 41)


def refine_kernel(phases: Real, step: float) -> Complex:
    """``seed^(-step·g)`` for the refinement grid g (cache it per factor; see
    :func:`refine_exponent`). Shapes: phases (n,) → (41, n)."""
    return np.asarray(np.exp(-1j * step * np.outer(_REFINE_GRID, phases)), np.complex128)


def refine_exponent(x: NDArray[np.complexfloating], phases: Real, value: float,
                    step: float, kernel: Complex | None = None) -> float:
    """The exponent t within ``value ± step`` that maximises ``Re<seed^t, x>``.

    Fractional powers of an FPE seed are band-limited shifts, so the similarity of a state to
    the codebook is a smooth function of the exponent between the entries; its maximum (41-point
    grid, then a parabola through the best three) is the readout without the pull towards
    whole entries that the sharpened state gives a population vector (pixel locking).

    Shapes:
        x, phases: (n,); kernel: (41, n), :func:`refine_kernel` of ``phases`` and ``step``.
    """
    grid = _REFINE_GRID         # t = value + step * grid, of which two entries are needed
    if kernel is None:
        kernel = refine_kernel(phases, step)
    sim = np.real(kernel @ (x * np.exp(-1j * value * phases)))
    j = int(np.argmax(sim))
    t_j = value + step * float(grid[j])
    if 0 < j < len(grid) - 1:
        den = float(sim[j - 1] - 2.0 * sim[j] + sim[j + 1])
        if den < 0.0:
            dt = (value + step * float(grid[1])) - (value + step * float(grid[0]))
            return float(t_j + 0.5 * float(sim[j - 1] - sim[j + 1]) / den * dt)
    return float(t_j)
