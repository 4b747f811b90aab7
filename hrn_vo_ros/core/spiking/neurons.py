"""Spiking phasor neurons: the phase-to-timing code and resonate-and-fire (RF) integration.

Phase-to-timing code (Frady & Sommer, "Robust computation with rhythmic spike patterns", PNAS
116(36):18050, 2019, doi:10.1073/pnas.1902653116): a complex value ``z = |z| e^{i phi}`` is one
spike per oscillation cycle of ``T`` time steps, at step

    t(z) = round(phi * T / (2 pi)) mod T,           phase resolution omega = 2 pi / T,

carrying a graded payload ``g = round(|z| / 2^e)`` in ``[0, 2^B - 1]`` (``B`` payload bits, ``e``
a per-population exponent; Loihi 2 graded spikes). With ``B = 1`` spikes are binary and carry the
phase only (TPAM: silent when ``|z|`` is below the firing threshold). A silent neuron has
``g = 0``.

Resonate-and-fire neuron, discrete time (the dynamics of Lava's ``RF`` process, ``proc/rf``, with
the oscillator turning clockwise by one phase step per time step and no decay):

    z[t+1] = e^{-i omega} (z[t] + a[t]),            z[0] = 0,                       (RF)

so that after one cycle a kick ``a`` at step ``t`` has turned by ``-omega (T - t) = omega t``
(mod 2 pi): ``z[T] = sum_t a[t] e^{i omega t}``. A presynaptic spike at ``t_j`` through a real
weight therefore adds ``w g_j e^{i phi_j}``, a complex *kick* ``(w_re, w_im)`` adds
``w g_j e^{i phi_j}`` with a complex ``w`` (complex synapse as a complex impulse), and a synaptic
*delay* ``d`` adds ``e^{i omega d}`` (complex synapse as a delay; binding is phase addition). The
neuron fires once in the next cycle when its turning state crosses the reference phase, i.e. at
step ``round(arg z[T] / omega)``, if ``|z[T]|`` reaches its threshold: its spike time encodes the
phase of the summed input and its (unit or graded) spike is the phasor projection ``f`` for free.

Fixed point (``precision='loihi'``; Lava's bit-accurate RF model uses 12-bit sin/cos constants and
a 24-bit state): with ``D`` fractional bits, ``c = round(cos(omega) 2^D)``,
``s = round(sin(omega) 2^D)``,

    re <- re + a_re ;  im <- im + a_im
    re, im <- rnd((c re + s im) / 2^D), rnd((-s re + c im) / 2^D)                  (RF-int)

with ``rnd`` round-half-up (an arithmetic shift after adding ``2^(D-1)``) and saturation at
``±(2^(S-1) - 1)`` (``S`` state bits). The loop over the ``T`` steps runs vectorised over neurons;
the kicks of all steps are gathered first (vectorised over time), so it costs ``T`` small array
operations per layer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import functools
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.spiking.config import SpikingConfig

Complex = NDArray[np.complex128]
Real = NDArray[np.float64]
Int = NDArray[np.int64]


@dataclass(frozen=True, slots=True, eq=False)
class Spikes:
    """One cycle of a population of phasor neurons.

    Attributes:
        t: Spike step in ``[0, T)`` per neuron (meaningless where ``g == 0``).
        g: Graded payload per neuron, ``0`` = silent.
        exp: Power-of-two exponent of the payload unit: the value is ``g 2^exp e^{i 2 pi t/T}``.
        steps: ``T``, the steps per cycle.

    Shapes:
        t, g: any shape (the population's layout), the same for both; int64.
    """

    t: Int
    g: Int
    exp: int
    steps: int

    @property
    def count(self) -> int:
        """Number of spikes (neurons that fired)."""
        return int(np.count_nonzero(self.g))

    def decode(self) -> Complex:
        """The complex values the spikes carry, ``g 2^exp e^{i 2 pi t / T}``."""
        unit = np.exp(2j * np.pi * np.arange(self.steps) / self.steps)
        out: Complex = np.ldexp(self.g.astype(np.float64), self.exp) * unit[self.t]
        return out

    def phasor(self) -> Complex:
        """Unit phasors at the spike phases (0 where silent)."""
        unit = np.exp(2j * np.pi * np.arange(self.steps) / self.steps)
        return np.where(self.g > 0, unit[self.t], 0.0)


class Rounding:
    """How a payload magnitude, in units of its population's payload unit, becomes an integer
    (``SpikingConfig.rounding``).

    To the nearest (``rng`` None, :data:`NEAREST`), or stochastically: up with the probability
    of the fraction, ``floor(x + u)`` with ``u`` uniform in [0, 1) from ``rng`` per neuron and
    cycle (dithered rounding: unbiased, so a change of less than half a unit still moves the
    mean of what a population sends, where rounding to the nearest can hold it in place cycle
    after cycle). The values stay within the population's range (``x <= 2^B - 1`` gives at most
    ``2^B - 1``).

    The same object rounds the spike steps (:meth:`step`): to the nearest step, or with
    ``phase_rng`` dithered, ``floor(arg(z) T / 2 pi + u) mod T`` (``SpikingConfig.
    phase_rounding``).

    Args:
        rng: The source of the uniform numbers (None: round to the nearest).
        phase_rng: The source of the spike steps' dither (None: the nearest step).
    """

    def __init__(self, rng: np.random.Generator | None = None, *,
                 phase_rng: np.random.Generator | None = None) -> None:
        self.rng = rng
        self.phase_rng = phase_rng

    def step(self, z: NDArray[np.complexfloating], steps: int) -> Int:
        """The spike step of each value: :func:`phase_to_step`, or dithered (``phase_rng``).

        Shapes:
            z: any; returns the same shape, int64 in ``[0, steps)``.
        """
        if self.phase_rng is None:
            return phase_to_step(z, steps)
        x = _dithered(np.angle(z) * (steps / (2.0 * np.pi)), self.phase_rng)
        out: Int = x.astype(np.int64) % steps
        return out

    def __call__(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        """``x`` rounded (a new array)."""
        if self.rng is None:
            out: NDArray[np.floating] = np.rint(x)
            return out
        return _dithered(x, self.rng)

    def inplace(self, x: NDArray[np.float32]) -> None:
        """``x`` (float32) rounded in place."""
        if self.rng is None:
            np.rint(x, out=x)
        else:
            x += self.rng.random(x.shape, dtype=np.float32)
            np.floor(x, out=x)


#: Round to the nearest (``SpikingConfig.rounding = 'nearest'``).
NEAREST = Rounding()


def _dithered(x: NDArray[np.floating], rng: np.random.Generator) -> NDArray[np.floating]:
    """``floor(x + u)``, ``u`` uniform in [0, 1) from ``rng`` per element (a new array):
    up with the probability of the fraction, so unbiased."""
    out: NDArray[np.floating] = np.floor(x + rng.random(np.shape(x)))
    return out


def phase_to_step(z: NDArray[np.complexfloating], steps: int) -> Int:
    """Spike step ``round(arg(z) T / 2 pi) mod T`` of each value, via :func:`phase_codes`.

    Shapes:
        z: any; returns the same shape, int64 in ``[0, steps)``.
    """
    return code_steps(steps).take(phase_codes(z, steps))


def phase_codes(z: NDArray[np.complexfloating], steps: int) -> NDArray[np.uint8]:
    """Each value's phase step as a code; ``code_steps(T)[code]`` is the step.

    For ``T`` a multiple of 4 (every configured ``T`` so far) without a transcendental function:
    the code is ``octant * K + k``, with the octant from the signs of ``x``, ``y`` and whether
    ``|y| > |x|``, and ``k`` the number of step boundaries ``tan((j + 1/2) 2 pi / T)`` below
    ``min(|x|, |y|) / max(|x|, |y|)`` (``K`` - 1 of them inside the first octant); the octant's
    symmetry (``k -> T/4 - k``, ``T/2 - k``, ``-k``) maps steps to steps exactly when ``4 | T``.
    Equal to rounding ``arctan2`` in float64 except within the input's precision of a boundary,
    and about 5x faster than ``arctan2`` in numpy (the emulation's largest cost). 0 gets the
    step 0. Other ``T``: the code is the step, from ``arctan2``.

    Shapes:
        z: any; returns the same shape, uint8 (``T <= 63``).
    """
    if steps % 4:
        step = np.rint(np.angle(z) * (steps / (2.0 * np.pi))).astype(np.int64) % steps
        out: NDArray[np.uint8] = step.astype(np.uint8)
        return out
    z = np.asarray(z)
    if z.ndim == 0:                      # (the in-place steps below need arrays)
        return phase_codes(z.reshape(1), steps).reshape(())
    x, y = z.real, z.imag
    ax, ay = np.abs(x), np.abs(y)
    hi = np.maximum(ax, ay)
    # the octant (4 sign(y) + 2 sign(x) + [|y| > |x|]) by Horner's rule on booleans viewed as
    # uint8 (in-place arithmetic: no casting passes)
    code: NDArray[np.uint8] = np.signbit(y).view(np.uint8)
    code += code
    code += np.signbit(x).view(np.uint8)
    code += code
    code += np.greater(ay, ax).view(np.uint8)
    bounds = _bound_column(steps, ax.dtype, ax.ndim)
    code *= np.uint8(bounds.shape[0] + 1)
    ratio = np.minimum(ax, ay, out=ax)
    with np.errstate(invalid='ignore', divide='ignore'):      # 0 / 0 at z = 0: no boundary
        ratio /= hi
    # k: the boundaries below the ratio, all compared in one pass (one row per boundary)
    code += np.greater(ratio, bounds).view(np.uint8).sum(axis=0, dtype=np.uint8)
    return code


@functools.cache
def _bound_column(steps: int, dtype: np.dtype[Any], ndim: int) -> NDArray[np.floating]:
    """:func:`_octant_bounds` in ``dtype`` (how a Python float compares with such an array),
    as a column ``(K, 1, ..., 1)`` against an ``ndim``-D ratio (read-only)."""
    out = np.array(_octant_bounds(steps), dtype).reshape((-1,) + (1,) * ndim)
    out.flags.writeable = False
    return out


@functools.cache
def code_steps(steps: int) -> Int:
    """The step of each code of :func:`phase_codes` (read-only)."""
    if steps % 4:
        out = np.arange(steps, dtype=np.int64)
    else:
        per = len(_octant_bounds(steps)) + 1
        octant, k = np.divmod(np.arange(8 * per), per)
        k = np.where(octant & 1, steps // 4 - k, k)          # |y| > |x|: mirrored at 45 deg
        k = np.where(octant & 2, steps // 2 - k, k)          # x < 0: mirrored at 90 deg
        out = np.where(octant & 4, -k, k) % steps            # y < 0: mirrored at 0
    out.flags.writeable = False
    return out


@functools.cache
def _octant_bounds(steps: int) -> tuple[float, ...]:
    """``tan`` of the step boundaries inside the first octant, ``(j + 1/2) 2 pi / T < pi / 4``
    (Python floats: compared in the input's precision)."""
    half = np.arange(steps // 8 + 1) + 0.5
    return tuple(np.tan(half[half < steps / 8] * (2.0 * np.pi / steps)).tolist())


def payload_exponent(max_value: float, bits: int) -> int:
    """Smallest power-of-two unit ``e`` with ``max_value / 2^e <= 2^bits - 1`` (a shared shift)."""
    top = (1 << bits) - 1
    if not max_value > 0.0 or not math.isfinite(max_value):
        return 0
    return math.ceil(math.log2(max_value / top))


def encode(z: Complex, cfg: SpikingConfig, *, fire_threshold: float | None = None,
           wide: NDArray[np.intp] | None = None, wide_bits: int = 0,
           rounding: Rounding = NEAREST) -> Spikes:
    """Send complex values as phase-coded spikes with graded payloads.

    The payload unit is a power of two chosen from the population's largest magnitude (a
    per-population shift, [design]); with ``payload_bits == 1`` every firing neuron carries the
    unit payload and the population unit is the power of two nearest the mean magnitude of the
    firing neurons (binary spikes keep the phase only).

    Args:
        z: Values to send.
        cfg: Steps per cycle, payload bits and the default firing threshold.
        fire_threshold: Neurons with ``|z| < fire_threshold * mean|z|`` stay silent (TPAM
            threshold); default ``cfg.fire_threshold``.
        wide: Flat indices of neurons with a wider payload of ``wide_bits`` (> payload_bits):
            the unit is then the smallest that holds the others in ``payload_bits`` and these
            in ``wide_bits``, so one dominant neuron (a spectrum's DC term) does not set the
            unit of all ([design], cleanup inputs; graded payloads, ``payload_bits`` >= 2).
        rounding: How the payloads are rounded (:class:`Rounding`; to the nearest).

    Shapes:
        z: any; the spikes have the same shape.
    """
    thr = cfg.fire_threshold if fire_threshold is None else fire_threshold
    mag = np.abs(z)
    t = rounding.step(z, cfg.steps_per_cycle)
    live = mag > 0.0
    if thr > 0.0 and mag.size:
        live &= mag >= thr * float(mag.mean())
    if cfg.payload_bits == 1:
        mean = float(mag[live].mean()) if live.any() else 0.0
        e = round(math.log2(mean)) if mean > 0.0 else 0
        return Spikes(t, live.astype(np.int64), e, cfg.steps_per_cycle)
    e = _population_exponent(mag, cfg, wide, wide_bits)
    g = np.where(live, rounding(np.ldexp(mag, -e)), 0.0).astype(np.int64)
    return Spikes(t, g, e, cfg.steps_per_cycle)


def _population_exponent(mag: NDArray[np.floating], cfg: SpikingConfig,
                         wide: NDArray[np.intp] | None, wide_bits: int) -> int:
    """The payload unit exponent of one population of magnitudes ``mag`` (graded payloads):
    its largest magnitude in ``payload_bits``, or, with ``wide`` neurons on ``wide_bits``,
    the smallest unit that holds the others in ``payload_bits`` and those in ``wide_bits``
    (:func:`encode`)."""
    if wide is not None and wide.size and wide_bits > cfg.payload_bits and mag.size:
        flat = mag.reshape(-1)
        rest = flat.copy()
        rest[wide] = 0.0
        return max(payload_exponent(float(rest.max()), cfg.payload_bits),
                   payload_exponent(float(flat[wide].max()), wide_bits))
    return payload_exponent(float(mag.max()) if mag.size else 0.0, cfg.payload_bits)


def encode_many(zs: list[Complex], cfg: SpikingConfig, *, fire_threshold: float | None = None,
                wides: list[NDArray[np.intp] | None] | None = None, wide_bits: int = 0,
                rounding: Rounding = NEAREST) -> list[Spikes]:
    """:func:`encode` of several populations, each with its own payload unit (and its own
    ``wide`` neurons), the per-neuron steps run once on all their neurons (the same spikes).

    Shapes:
        zs: any each (one dtype for all); the spikes have the same shapes.
    """
    thr = cfg.fire_threshold if fire_threshold is None else fire_threshold
    wl = [None] * len(zs) if wides is None else wides
    if (len(zs) < 2 or cfg.payload_bits == 1 or thr > 0.0
            or len({np.asarray(z).dtype for z in zs}) > 1):
        return [encode(z, cfg, fire_threshold=thr, wide=w, wide_bits=wide_bits,
                       rounding=rounding)
                for z, w in zip(zs, wl, strict=True)]
    flat = np.concatenate([np.ravel(z) for z in zs])
    mag = np.abs(flat)
    t = rounding.step(flat, cfg.steps_per_cycle)
    sizes = [np.size(z) for z in zs]
    ends = np.cumsum(sizes)
    exps = [_population_exponent(mag[end - n:end], cfg, w, wide_bits)
            for n, end, w in zip(sizes, ends, wl, strict=True)]
    e = np.repeat(-np.array(exps, np.int64), sizes)
    g = np.where(mag > 0.0, rounding(np.ldexp(mag, e)), 0.0).astype(np.int64)
    return [Spikes(t[end - n:end].reshape(np.shape(z)), g[end - n:end].reshape(np.shape(z)),
                   ez, cfg.steps_per_cycle)
            for z, n, end, ez in zip(zs, sizes, ends, exps, strict=True)]


def rotation_constants(cfg: SpikingConfig) -> tuple[int, int]:
    """Fixed-point ``(c, s) = round((cos omega, sin omega) 2^D)`` of (RF-int)."""
    omega = 2.0 * np.pi / cfg.steps_per_cycle
    scale = float(1 << cfg.decay_bits)
    return round(math.cos(omega) * scale), round(math.sin(omega) * scale)


def rf_cycle_float(kicks: Complex) -> Complex:
    """End-of-cycle state of float RF neurons (RF), vectorised over neurons and steps.

    Args:
        kicks: ``a[n, t]``, the summed complex input of neuron ``n`` at step ``t``.

    Shapes:
        kicks: (n, T); returns (n,) ``z[T] = sum_t a[t] e^{i omega t}``.
    """
    steps = kicks.shape[-1]
    out: Complex = kicks @ np.exp(2j * np.pi * np.arange(steps) / steps)
    return out


def rf_cycle_int(kick_re: Int, kick_im: Int, cfg: SpikingConfig) -> tuple[Int, Int, int]:
    """End-of-cycle integer state of fixed-point RF neurons (RF-int).

    Args:
        kick_re: Real part of the integer input per neuron and step.
        kick_im: Imaginary part, same shape.
        cfg: Steps per cycle, rotation and state bits.

    Returns:
        ``(re, im, saturated)``: the state after ``T`` steps and the number of neuron-steps that
        hit the state bound.

    Shapes:
        kick_re, kick_im: (n, T); re, im: (n,).
    """
    kicks = np.stack([kick_re.T, kick_im.T], axis=1).astype(np.float64)
    return rf_cycle_kicks(kicks, cfg)


def rf_cycle_kicks(kicks: Real, cfg: SpikingConfig) -> tuple[Int, Int, int]:
    """:func:`rf_cycle_int` with the kicks in the step loop's layout: ``kicks[t, 0]`` and
    ``kicks[t, 1]`` are the real and imaginary integer inputs of all neurons at step ``t``, held
    as float64 (integers below ``2^53``, so every sum of them is exact).

    Shapes:
        kicks: (T, 2, n); re, im: (n,) int64.
    """
    c, s = rotation_constants(cfg)
    shift = cfg.decay_bits
    half = 1 << (shift - 1)
    bound = (1 << (cfg.state_bits - 1)) - 1
    steps, _, n = kicks.shape
    # No step can saturate if the whole cycle's input, grown by the rotation's gain and the
    # rounding (<= 1 per step and component), stays inside the bound: then skip the checks
    # (same result, a third of the operations).
    gain = max(1.0, math.hypot(c, s) / float(1 << shift)) ** steps
    mass = float(np.abs(kicks).sum(axis=(0, 1)).max(initial=0))
    if (mass + 2 * steps) * gain < bound:
        return _rf_loop_unchecked(kicks, c, s, shift, half)
    k = kicks.astype(np.int64)
    re = np.zeros(n, np.int64)
    im = np.zeros(n, np.int64)
    saturated = 0
    for t in range(steps):
        re += k[t, 0]
        im += k[t, 1]
        re, im = (c * re + s * im + half) >> shift, (c * im - s * re + half) >> shift
        over = (np.abs(re) > bound) | (np.abs(im) > bound)
        if over.any():
            saturated += int(over.sum())
            np.clip(re, -bound, bound, out=re)
            np.clip(im, -bound, bound, out=im)
    return re, im, saturated


def rf_cycle_populations(fills: list[Callable[[Real], None]], sizes: list[int],
                         cfg: SpikingConfig) -> tuple[list[tuple[Int, Int]], int]:
    """:func:`rf_cycle_kicks` of several populations as one (the same per-neuron arithmetic,
    one step loop): ``fills[i]`` writes population ``i``'s kicks into its ``(T, 2, sizes[i])``
    slice (zeros on entry). Returns each population's ``(re, im)`` and the saturations of all.

    Shapes:
        returns re, im: (sizes[i],) int64 each.
    """
    kicks = np.zeros((cfg.steps_per_cycle, 2, sum(sizes)))
    ends = np.cumsum(sizes, dtype=np.intp)
    for fill, n, end in zip(fills, sizes, ends, strict=True):
        fill(kicks[:, :, end - n:end])
    re, im, sat = rf_cycle_kicks(kicks, cfg)
    return [(re[end - n:end], im[end - n:end]) for n, end in zip(sizes, ends, strict=True)], sat


def _rf_loop_unchecked(kicks: Real, c: int, s: int, shift: int, half: int
                       ) -> tuple[Int, Int, int]:
    """(RF-int) without saturation checks: ``(re, im) <- floor(M (re, im, 1) / 2^shift)`` with
    ``M = [[c, s, half], [-s, c, half]]`` (the rounding offset as a third column), one matrix
    product per step, in float64 (``M / 2^shift``): the caller's bound keeps ``|re|, |im|``
    below ``2^(S-1)`` (``S`` state bits), so every product and partial sum is a multiple of
    ``2^-shift`` below ``2^S``, at most ``S + shift <= 48`` significant bits: exact in any
    order, and ``floor`` of it is the arithmetic shift of the integer form.

    Shapes:
        kicks: (T, 2, n) as :func:`rf_cycle_kicks`; returns (n,) int64 twice.
    """
    steps, _, n = kicks.shape
    z = np.zeros((3, n))
    z[2] = 1.0
    state = z[:2]
    rot = np.array([[c, s, half], [-s, c, half]], np.float64) * 2.0 ** -shift
    tmp = np.empty((2, n))
    for t in range(steps):
        state += kicks[t]
        np.matmul(rot, z, out=tmp)
        np.floor(tmp, out=state)
    out = state.astype(np.int64)
    return out[0], out[1], 0
