"""Complex synapses between phasor populations, with Loihi weight and delay limits.

Weights (Davies et al. 2018; the brian2_loihi emulator): a synaptic weight is a signed
integer mantissa of ``B`` bits (``weight_bits``; Loihi: 8, reduced by ``num_weight_bits``) times a
power of two shared by all synapses of one connection (Loihi: ``2^(6 + wgt_exp)``,
``wgt_exp`` in [-8, 7]). Here the shared exponent is chosen so that the largest weight component
of the connection uses the full mantissa range ``[-2^(B-1), 2^(B-1) - 1]``; the absolute range of
``wgt_exp`` is not enforced because the emulation's value unit is arbitrary ([design]).

Two realisations of a complex weight ``w = |w| e^{i psi}``:

* ``synapse='kick'``: a complex impulse into a resonate-and-fire neuron, two real weights
  ``(Re w, Im w)`` (two synaptic operations per spike, like Lava's RF with real and imaginary
  dense inputs). Quantisation error: the ``B``-bit mantissa of each component.
* ``synapse='delay'``: a real weight ``|w|`` and a delay ``d = round(psi T / 2 pi) mod T <= T - 1
  <= max_delay`` (one synaptic operation). Timing error: ``psi`` on the ``2 pi / T`` grid.

In the steady state the input repeats every cycle, so one window of ``T`` steps sees every input
exactly once, at step ``(t_j + d) mod T`` ([design]: the emulation integrates that window).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.neurons import (
    phase_to_step,
    rf_cycle_populations,
    Spikes,
)
from hrn_vo_ros.errors import ConfigError

Complex = NDArray[np.complex128]
Real = NDArray[np.float64]
Int = NDArray[np.int64]


@dataclass(frozen=True, slots=True, eq=False)
class QuantisedWeights:
    """Integer weight mantissas with one shared power-of-two exponent.

    Attributes:
        re: Real mantissas. im: Imaginary mantissas (zero for real weights).
        exp: Shared exponent: the weight is ``(re + i im) 2^exp``.

    Shapes:
        re, im: the weight matrix's shape, int64.
    """

    re: Int
    im: Int
    exp: int

    def value(self) -> Complex:
        """The quantised weights as complex numbers."""
        return np.asarray((self.re + 1j * self.im) * 2.0**self.exp, dtype=np.complex128)


def quantise_weights(w: Complex | Real, bits: int) -> QuantisedWeights:
    """Round weights to ``bits``-bit signed mantissas with one shared exponent.

    The relative error of the largest component is at most ``2^-(bits-1)``; every component's
    absolute error is at most half a mantissa step, ``2^(exp-1)``.

    Shapes:
        w: any; the mantissas have the same shape.
    """
    if bits < 2:
        raise ConfigError(f'signed weights need at least 2 bits, got weight_bits = {bits}')
    wc = np.asarray(w, dtype=np.complex128)
    top = (1 << (bits - 1)) - 1
    largest = float(max(np.abs(wc.real).max(initial=0.0), np.abs(wc.imag).max(initial=0.0)))
    exp = math.ceil(math.log2(largest / top)) if largest > 0.0 else 0
    lo = -(1 << (bits - 1))
    re = np.clip(np.rint(np.ldexp(wc.real, -exp)), lo, top).astype(np.int64)
    im = np.clip(np.rint(np.ldexp(wc.imag, -exp)), lo, top).astype(np.int64)
    return QuantisedWeights(re, im, exp)


#: Range of Loihi's weight scale ``2^(6 + wgt_exp)``, ``wgt_exp`` in [-8, 7] (brian2_loihi).
SHIFT_RANGE = (-2, 13)


def _fit_shift(worst: float, cfg: SpikingConfig) -> int:
    """Largest shift in ``SHIFT_RANGE`` that keeps ``worst * 2^shift`` inside the state bits."""
    bound = (1 << (cfg.state_bits - 1)) - 1
    if worst <= 0:
        return SHIFT_RANGE[1]
    # 1/8 headroom: the fixed-point rotation's gain |c + i s| / 2^D may exceed 1 a little.
    return int(np.clip(math.floor(math.log2(bound / (1.125 * worst))), *SHIFT_RANGE))


def state_shift(q: QuantisedWeights, cfg: SpikingConfig, tops: Int | None = None) -> int:
    """The left shift from ``mantissa * payload`` into the neuron state (Loihi ``6 + wgt_exp``).

    Chosen per connection as the largest value in ``SHIFT_RANGE`` for which the worst-case input
    of one cycle (every presynaptic neuron at full payload, all kicks aligned) cannot exceed the
    state bits, so the integer state never saturates and keeps as many fractional bits as it can
    ([design]; a hardware mapping would pick ``wgt_exp`` the same way). ``tops``: the largest
    payload of each presynaptic neuron (default ``2^payload_bits - 1`` for all).
    """
    mags = np.abs(q.re) + np.abs(q.im)
    top = np.full(mags.shape[-1], (1 << cfg.payload_bits) - 1) if tops is None else tops
    return _fit_shift(float((mags @ np.asarray(top, np.float64)).max(initial=0)), cfg)


def scale_kicks_float(k: Real, shift: int) -> None:
    """``k * 2^shift`` in place on integer kicks held as float64 (exact below ``2^53``): the
    arithmetic shift of the integer kicks, a right shift rounding half up."""
    if shift >= 0:
        k *= 2.0 ** shift
    else:
        k += float(1 << (-shift - 1))
        k *= 2.0 ** shift
        np.floor(k, out=k)


@dataclass(slots=True)
class LayerCounts:
    """Operation counts of one layer for one cycle (accumulated over a run by the caller)."""

    spikes_in: int = 0
    synops: int = 0
    neuron_updates: int = 0
    saturated: int = 0


@dataclass(slots=True, eq=False)
class ComplexSynapses:
    """Dense complex synapses from ``n_in`` phasor neurons onto ``n_out`` RF neurons.

    Args:
        weights: The complex weight matrix ``W`` (row = target neuron).
        cfg: Spiking settings (realisation, bits, precision).
        name: Layer name for the accounting.
        tops: Largest payload of each presynaptic neuron, for the state shift (default
            ``2^payload_bits - 1`` for all).

    Shapes:
        weights: (n_out, n_in); tops: (n_in,).
    """

    weights: Complex
    cfg: SpikingConfig
    name: str = 'synapses'
    tops: Int | None = None
    _eff: Complex = field(init=False)
    _q: QuantisedWeights | None = field(init=False, default=None)
    _delay: Int | None = field(init=False, default=None)
    _nnz_col: Int = field(init=False)
    _shift: int = field(init=False, default=0)
    _qt: Real | None = field(init=False, default=None)
    _qt32: NDArray[np.float32] | None = field(init=False, default=None)
    _top: Int | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        w = np.asarray(self.weights, dtype=np.complex128)
        if w.ndim != 2:
            raise ConfigError(f'{self.name}: the weight matrix must be 2-D, got {w.shape}')
        if w.shape[1] > self.cfg.max_fan_in:
            msg = (f'{self.name}: fan-in {w.shape[1]} exceeds SpikingConfig.max_fan_in = '
                   f'{self.cfg.max_fan_in}; split the layer (e.g. marginalise first) or raise '
                   f'max_fan_in')
            raise ConfigError(msg)
        steps = self.cfg.steps_per_cycle
        omega = 2.0 * np.pi / steps
        if self.cfg.synapse == 'delay':
            self._delay = phase_to_step(w, steps)
            if int(self._delay.max(initial=0)) > self.cfg.max_delay:
                raise ConfigError(f'{self.name}: a delay exceeds max_delay = '
                                  f'{self.cfg.max_delay}; choose fewer steps_per_cycle')
            mag = np.abs(w)
            if self.cfg.quantised:
                self._q = quantise_weights(mag, self.cfg.weight_bits)
                mag = self._q.value().real
            self._eff = mag * np.exp(1j * omega * self._delay)
        else:
            if self.cfg.quantised:
                self._q = quantise_weights(w, self.cfg.weight_bits)
                self._eff = self._q.value()
            else:
                self._eff = w
        if self._q is not None:
            self._shift = state_shift(self._q, self.cfg, self.tops)
            # (re | im) mantissas per presynaptic neuron as float64 rows: kick products below
            self._qt = np.ascontiguousarray(
                np.concatenate([self._q.re, self._q.im]).T.astype(np.float64))
            # float32 holds every partial sum of the products exactly while each target's
            # sum of |mantissa| x largest payload stays below 2^24
            self._top = (np.full(w.shape[1], (1 << self.cfg.payload_bits) - 1, np.int64)
                         if self.tops is None else np.asarray(self.tops, np.int64))
            mags = np.abs(self._q.re) + np.abs(self._q.im)
            if float((mags @ self._top.astype(np.float64)).max(initial=0)) < 2.0 ** 24:
                self._qt32 = self._qt.astype(np.float32)
        per_syn = 2 if self.cfg.synapse == 'kick' else 1
        self._nnz_col = per_syn * np.count_nonzero(w, axis=0).astype(np.int64)

    @property
    def effective(self) -> Complex:
        """The complex weights as realised (quantised mantissas, or delays on the grid)."""
        return self._eff

    def drive(self, spikes: Spikes, counts: LayerCounts | None = None) -> Complex:
        """End-of-cycle state of the target neurons, in value units.

        ``precision='float'`` evaluates (RF) in closed form (``W_eff`` times the decoded spikes);
        ``'loihi'`` gathers the integer kicks per step and runs (RF-int).

        Shapes:
            spikes: (n_in,); returns (n_out,) complex128.
        """
        return drive_many([(self, spikes, counts)])[0]

    def count(self, spikes: Spikes, counts: LayerCounts | None) -> None:
        """Add one cycle of this connection to ``counts``."""
        if counts is not None:
            fired = spikes.g > 0
            counts.spikes_in += int(fired.sum())
            counts.synops += int(self._nnz_col[fired].sum())
            counts.neuron_updates += self._eff.shape[0] * self.cfg.steps_per_cycle

    def kicks(self, spikes: Spikes) -> tuple[Int, Int]:
        """The integer kicks per target neuron and step, shifted into the state
        (``precision='loihi'`` only). Shapes: (n_out, T) each."""
        k = np.zeros((self.cfg.steps_per_cycle, 2, self._eff.shape[0]))
        self.kicks_into(spikes, k)
        ki = k.astype(np.int64)
        return np.ascontiguousarray(ki[:, 0].T), np.ascontiguousarray(ki[:, 1].T)

    def kicks_into(self, spikes: Spikes, out: Real) -> None:
        """:meth:`kicks` in the step loop's layout of :func:`~.neurons.rf_cycle_kicks`, written
        into ``out`` (zeros on entry; integers held as float64).

        ``synapse='kick'``: the spikes of each step that has any, as rows of payloads, times the
        mantissa matrix (one product for re and im; integers below ``2^53``: exact; in float32
        when the payloads are within the largest ones the connection was sized for and its
        sums stay below ``2^24``: exact as well).

        Shapes:
            spikes: (n_in,); out: (T, 2, n_out).
        """
        assert self._q is not None and self._qt is not None
        n_out = self._eff.shape[0]
        steps = self.cfg.steps_per_cycle
        if self.cfg.synapse == 'kick':
            live = np.flatnonzero(spikes.g)
            if live.size:
                t = spikes.t[live]
                per_step = np.bincount(t, minlength=steps)
                present = np.flatnonzero(per_step)
                slot = np.cumsum(per_step > 0) - 1
                single = (self._qt32 is not None and self._top is not None
                          and bool(np.all(spikes.g <= self._top)))
                rows = np.zeros((present.size, spikes.g.size),
                                np.float32 if single else np.float64)
                rows[slot[t], live] = spikes.g[live]
                if single:
                    assert self._qt32 is not None
                    k = (rows @ self._qt32).astype(np.float64)
                else:
                    k = rows @ self._qt
                scale_kicks_float(k, self._shift)     # (a step without spikes stays 0)
                out[present] = k.reshape(present.size, 2, n_out)
        else:
            assert self._delay is not None
            arrive = (spikes.t[None, :] + self._delay) % steps            # (n_out, n_in)
            idx = (arrive * n_out + np.arange(n_out)[:, None]).ravel()
            wts = (self._q.re * spikes.g[None, :]).ravel().astype(np.float64)
            out[:, 0] += np.rint(np.bincount(idx, wts, n_out * steps)).reshape(steps, n_out)
            scale_kicks_float(out, self._shift)

    def finish(self, re: Int, im: Int, spikes: Spikes) -> Complex:
        """The integer end-of-cycle state in value units."""
        assert self._q is not None
        return np.asarray((re + 1j * im) * 2.0**(self._q.exp + spikes.exp - self._shift),
                          dtype=np.complex128)


def drive_many(jobs: list[tuple[ComplexSynapses, Spikes, LayerCounts | None]]) -> list[Complex]:
    """:meth:`ComplexSynapses.drive` of several connections (one shared configuration): the
    integer dynamics of all their target neurons run as one population (the same per-neuron
    arithmetic, one step loop instead of one per connection)."""
    out: list[Complex | None] = [None] * len(jobs)
    ints: list[int] = []
    for i, (syn, sp, counts) in enumerate(jobs):
        syn.count(sp, counts)
        if syn._q is None:
            out[i] = np.asarray(syn._eff @ sp.decode(), dtype=np.complex128)
        else:
            ints.append(i)
    if ints:
        cfg = jobs[ints[0]][0].cfg
        states, sat = rf_cycle_populations(
            [functools.partial(jobs[i][0].kicks_into, jobs[i][1]) for i in ints],
            [jobs[i][0]._eff.shape[0] for i in ints], cfg)
        for i, (re, im) in zip(ints, states, strict=True):
            syn, sp, counts = jobs[i]
            if counts is not None:
                counts.saturated += sat if len(ints) == 1 else 0
            out[i] = syn.finish(re, im, sp)
    return [o for o in out if o is not None]
