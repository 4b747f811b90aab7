"""Λ and Λ' as sparse spiking layers: butterfly Fourier stages around the log-polar taps.

The fast path's transforms (``core/hrn/logpolar.py``, direct form of ``core/hrn/fast.py``)

    S_θ = fft_θ(T · canvas)                        (the frame, once per frame)
    p̂   = Λ' S_θ-spectrum = fft2_C(T' · ifft_θ(q))  (q = S_θ ⊙ r̂*, every iteration)
    l̂_θ = fft_θ(T · ifft2_C(x))                    (x = m̂ ⊙ v̂ ⊙ ĥ, every iteration)

become chains of phasor-neuron layers: every butterfly stage of every 1-D DFT
(:mod:`.butterfly`, fan-in = its radix) and the bilinear resampling ``T`` (``T'``) with at most 4
real taps per output neuron are one layer each. Every layer's neurons integrate their inputs over
one cycle and fire one phase-coded graded spike (:class:`PhasorCode`, the code of
:func:`~hrn_vo_ros.core.spiking.neurons.encode`: phase on the ``2 pi / T`` grid,
``transform_payload_bits`` payload with a per-population power-of-two unit: 8 bits by default;
a 2-D spectrum's DC and lowest frequencies set the unit, and on dense frames a fifth to a third
of the map's and of ``Λ'``'s last stage's neurons round to silence, which 12 bits avoid); with
``precision='loihi'`` the weights are ``weight_bits`` mantissas with one exponent per layer
(:func:`~.synapses.quantise_weights`) and a spike sent at step ``t`` arrives turned by the
fixed-point rotation ``rho^(T - t)`` of the receiving RF neuron (``rho = (c - i s) / 2^D``,
the constants of :func:`~hrn_vo_ros.core.spiking.neurons.rotation_constants`).

Emulation ([design], stated for honesty): a layer's end-of-cycle state is computed in closed
form, ``sum_j w_j g_j rho^(T - t_j)``, in complex64; the per-step rounding of the 24-bit integer
state is not emulated here, unlike in the cleanup layers
(:func:`~hrn_vo_ros.core.spiking.neurons.rf_cycle_int`). It is at most ``T`` half-LSBs of a
state whose shift fits the worst case (fan-in <= 4, full weights and payloads) in 24 bits: with
8-bit payloads >= 2^4 LSBs per unit kick; with 12-bit payloads (and 8-bit weights) the worst
case 4 x 127 x 4095 is just below 2^21, the shift keeps >= 2 LSBs per unit kick, and a
population whose largest output reaches 1/2^k of its worst case keeps >= 2^(10-k) LSBs per unit
of its own payload: the rounding (at most 16 LSBs, about 1.6 rms: ``sqrt(T)`` random
half-LSBs) stays below that payload's own rounding (half a unit, 0.29 rms) for k <= 4.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
import math

import numpy as np
from numpy.typing import NDArray
import scipy.sparse as sp

from hrn_vo_ros.core.hrn.logpolar import cart_to_lp_matrix, Geometry, lp_to_cart_matrix
from hrn_vo_ros.core.spiking.butterfly import AxisDFT, exact_weights, WeightMap
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.neurons import (
    code_steps,
    NEAREST,
    payload_exponent,
    phase_codes,
    rotation_constants,
)
from hrn_vo_ros.core.spiking.synapses import LayerCounts, quantise_weights

C64 = NDArray[np.complex64]
Int = NDArray[np.int64]


class PhasorCode:
    """What a population of phasor neurons passes on: its values as one graded spike each.

    ``fire(z)`` returns ``g 2^e u[t]`` with ``t = round(arg z T / 2 pi) mod T``,
    ``g = round(|z| / 2^e)`` in ``[0, 2^B - 1]`` (``rounding``, to the nearest unless the
    engine sets a stochastic one; ``B = cfg.transform_bits``, ``e`` from the
    population's largest magnitude; ``B = 1``: unit payloads, the unit nearest the mean
    magnitude) and ``u[t]`` the phase a spike at step ``t`` has at the end of the receiving
    neuron's cycle (``e^{i 2 pi t / T}``; ``precision='loihi'``: ``rho^(T - t)``).
    ``last_count`` is the number of neurons that fired. ``label`` names the population that
    fires next (set by its layer); ``probe``, when set, is called as ``probe(label, z, out)``
    after each fire (a diagnostic: :class:`hrn_vo_ros.core.spiking.report.PayloadProbe`).
    """

    def __init__(self, cfg: SpikingConfig) -> None:
        self.cfg = cfg
        self.bits = cfg.transform_bits
        steps = cfg.steps_per_cycle
        t = np.arange(steps)
        if cfg.quantised:
            c, s = rotation_constants(cfg)
            rho = complex(c, -s) / float(1 << cfg.decay_bits)
            table = rho ** (steps - t).astype(np.float64)
        else:
            table = np.exp(2j * np.pi * t / steps)
        self.table = table.astype(np.complex64)                     # per step
        self._by_code = self.table[code_steps(steps)]               # per phase code
        self.last_count = 0
        self.last_silent: NDArray[np.intp] | None = None   # flat indices of the silent neurons
        self.label = ''
        self.probe: Callable[[str, C64, C64], None] | None = None
        self.rounding = NEAREST

    def fire(self, z: C64) -> C64:
        """The values the population's spikes carry (same shape as ``z``)."""
        out = self._fire(z)
        if self.probe is not None:
            self.probe(self.label, z, out)
        return out

    def _fire(self, z: C64) -> C64:
        cfg = self.cfg
        mag = np.abs(z)
        top = float(mag.max()) if mag.size else 0.0
        self.last_silent = None
        if not top > 0.0:
            self.last_count = 0
            return np.zeros_like(z)
        code = phase_codes(z, cfg.steps_per_cycle)
        if self.bits == 1:
            ph = self._by_code.take(code)
            live = mag > 0.0
            if cfg.fire_threshold > 0.0:
                live &= mag >= cfg.fire_threshold * float(mag.mean())
            self.last_count = int(np.count_nonzero(live))
            mean = float(mag[live].mean()) if self.last_count else 0.0
            unit = 2.0 ** round(math.log2(mean)) if mean > 0.0 else 0.0
            ph *= np.where(live, np.float32(unit), np.float32(0.0))
            return ph
        e = payload_exponent(top, self.bits)
        ph = (self._by_code * np.float32(2.0 ** e)).take(code)   # unit 2^e: exact
        silent = (mag < cfg.fire_threshold * float(mag.mean()) if cfg.fire_threshold > 0.0
                  else None)
        g = mag                                               # (in place: mag is not used again)
        g *= np.float32(2.0 ** -e)
        self.rounding.inplace(g)
        if silent is not None:
            g[silent] = 0.0
        self.last_silent = np.flatnonzero(g == 0.0)
        self.last_count = g.size - self.last_silent.size
        ph *= g
        return ph


def weight_map(cfg: SpikingConfig) -> WeightMap:
    """How a layer realises its float weights: exact (``precision='float'``), ``weight_bits``
    mantissas of each component (``synapse='kick'``), or a ``weight_bits`` magnitude and a delay
    on the ``2 pi / T`` grid (``synapse='delay'``, one component per synapse)."""
    if not cfg.quantised and cfg.synapse == 'kick':
        return exact_weights

    def realise(w: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], Int]:
        if cfg.synapse == 'delay':
            steps = cfg.steps_per_cycle
            d = np.rint(np.angle(w) * steps / (2.0 * np.pi)) % steps
            mag = np.abs(w)
            if cfg.quantised:
                mag = quantise_weights(mag, cfg.weight_bits).value().real
            return mag * np.exp(2j * np.pi * d / steps), (mag > 0).astype(np.int64)
        q = quantise_weights(w, cfg.weight_bits)
        return q.value(), (q.re != 0).astype(np.int64) + (q.im != 0)

    return realise


@dataclass(slots=True)
class TapLayer:
    """A bilinear resampling layer: at most 4 real taps per output neuron (CSR).

    Attributes:
        matrix: The realised weights (complex64 CSR for the emulation).
        col_synops: Synaptic operations per firing input neuron (its nonzero outgoing taps).
        synapses: Nonzero taps. fan_in: Largest number of taps into one neuron.
    """

    matrix: sp.csr_matrix
    col_synops: NDArray[np.float64]
    synapses: int
    fan_in: int

    @classmethod
    def build(cls, m: sp.csr_matrix, cfg: SpikingConfig) -> TapLayer:
        """Realise the float resampling matrix ``m`` with ``cfg``'s weights."""
        m = m.tocsr().copy()
        m.eliminate_zeros()
        if cfg.quantised:
            m.data = quantise_weights(m.data, cfg.weight_bits).value().real
            m.eliminate_zeros()
        col = np.asarray((m != 0).sum(axis=0), np.float64).ravel()
        fan_in = int(np.diff(m.indptr).max(initial=0))
        return cls(m.astype(np.complex64), col, int(m.nnz), fan_in)


@dataclass(slots=True, eq=False)
class SparseTransforms:
    """The fast path's transforms as spiking layers (see the module docstring).

    Args:
        g: The geometry.
        cfg: Spiking settings (``max_radix``, precision, bits).

    Attributes:
        counts: Spikes in, synaptic operations and neuron updates per layer group since the
            last :meth:`reset_counts`.
    """

    g: Geometry
    cfg: SpikingConfig
    counts: dict[str, LayerCounts] = field(init=False)
    code: PhasorCode = field(init=False)
    axes: dict[str, AxisDFT] = field(init=False)
    T: TapLayer = field(init=False)
    Tr: TapLayer = field(init=False)
    _comp_cache: dict[tuple[str, int, int], Int] = field(init=False, default_factory=dict)
    _total: dict[tuple[str, int, int], int] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        cfg, g = self.cfg, self.g
        wm = weight_map(cfg)
        fact = cfg.synapse == 'kick'

        def axis(n: int, inverse: bool) -> AxisDFT:
            return AxisDFT(n, inverse=inverse, max_radix=cfg.max_radix, weight_map=wm,
                           dtype=np.complex64, factorised=fact)

        self.axes = {'fθ': axis(g.n_theta, False), 'iθ': axis(g.n_theta, True),
                     'fx': axis(g.canvas_width, False), 'ix': axis(g.canvas_width, True),
                     'fy': axis(g.canvas_height, False), 'iy': axis(g.canvas_height, True)}
        self.T = TapLayer.build(cart_to_lp_matrix(g), cfg)
        self.Tr = TapLayer.build(lp_to_cart_matrix(g), cfg)
        self.code = PhasorCode(cfg)
        self.counts = {}

    # -- the three transforms --------------------------------------------------------------

    def frame(self, canvas: NDArray[np.floating]) -> C64:
        """``S_θ = fft_θ(T · canvas)``: pixel neurons, the T taps, the θ stages.

        Shapes:
            canvas: (H_c, W_c) real; returns (n_rho, n_theta) complex64.
        """
        g = self.g
        self.code.label = 'S: pixels'
        pix = self.code.fire(np.asarray(canvas, np.complex64).ravel())
        lp = self._taps(self.T, pix, self.code.last_count, 'S: T taps (pixels → log-polar)')
        lp = lp.reshape(g.n_rho, g.n_theta)
        return self._axis(lp, 'fθ', 1, 'S: fft_θ stages')

    def reverse(self, q: C64, prefix: str = "Λ'") -> C64:
        """``Λ'`` from a θ-spectrum: ``fft2_C(T' · ifft_θ(q))``.

        Shapes:
            q: (n_rho, n_theta); returns (H_c, W_c) complex64.
        """
        g = self.g
        img = self._axis(q, 'iθ', 1, f'{prefix}: ifft_θ stages', fire_input=True)
        cart = self._taps(self.Tr, img.ravel(), self.code.last_count, f"{prefix}: T' taps")
        cart = cart.reshape(g.canvas_height, g.canvas_width)
        cart = self._axis(cart, 'fy', 0, f'{prefix}: fft_y stages')
        return self._axis(cart, 'fx', 1, f'{prefix}: fft_x stages')

    def forward(self, x: C64) -> C64:
        """``Λ`` without its ρ-DFT: ``fft_θ(T · ifft2_C(x))``.

        Shapes:
            x: (H_c, W_c); returns (n_rho, n_theta) complex64.
        """
        g = self.g
        img = self._axis(x, 'iy', 0, 'Λ: ifft_y stages', fire_input=True)
        img = self._axis(img, 'ix', 1, 'Λ: ifft_x stages')
        lp = self._taps(self.T, img.ravel(), self.code.last_count, 'Λ: T taps')
        return self._axis(lp.reshape(g.n_rho, g.n_theta), 'fθ', 1, 'Λ: fft_θ stages')

    # -- layers ------------------------------------------------------------------------------

    def _count(self, name: str, spikes: int, synops: int, neurons: int) -> None:
        c = self.counts.setdefault(name, LayerCounts())
        c.spikes_in += spikes
        c.synops += synops
        c.neuron_updates += neurons * self.cfg.steps_per_cycle

    def _taps(self, layer: TapLayer, x: C64, live: int, name: str) -> C64:
        # (all taps, less those of the silent inputs: the same integer count)
        synops = (layer.synapses if live == x.size
                  else layer.synapses - int(layer.col_synops[np.flatnonzero(x == 0)].sum()))
        self._count(name, live, synops, layer.matrix.shape[0])
        self.code.label = name
        return self.code.fire(np.asarray(layer.matrix @ x, np.complex64))

    def _axis(self, x: C64, key: str, axis: int, name: str, fire_input: bool = False) -> C64:
        """The stages of one axis; ``fire_input``: the input is a binding population whose
        spikes the first stage receives (its count is taken here)."""
        ax = self.axes[key]
        front = ax.to_front(np.asarray(x, np.complex64), axis)
        # the silent inputs in the stages' layout (from the input here; then from each fire)
        silent: NDArray[np.intp] | None = None
        if fire_input:
            silent = np.flatnonzero(front == 0)
            live = front.size - silent.size
        else:
            live = self.code.last_count
            if live != front.size:
                silent = np.flatnonzero(front == 0)
        spikes = synops = neurons = 0
        for i, s in enumerate(ax.stages):
            full = self._comps(key, i, front.shape[1])
            if live == front.size:
                synops += self._total[key, i, front.shape[1]]
            elif silent is not None:
                # (all synaptic operations less those of the silent inputs)
                synops += self._total[key, i, front.shape[1]] - int(full[silent].sum())
            else:
                synops += ax.spike_synops(front != 0, s)
            spikes += live
            neurons += front.size
            self.code.label = f'{name} {i + 1}/{len(ax.stages)}'
            front = self.code.fire(ax.stage(front, s))
            live, silent = self.code.last_count, self.code.last_silent
        self._count(name, spikes, synops, neurons)
        return ax.from_front(front, x.shape, axis)

    def _comps(self, key: str, i: int, post: int) -> Int:
        """Synaptic operations of each input neuron of stage ``i`` of axis ``key`` (flat, in the
        stages' (n, post) layout), cached with their total."""
        got = self._comp_cache.get((key, i, post))
        if got is None:
            ax = self.axes[key]
            s = ax.stages[i]
            got = np.repeat(np.tile(s.comps, ax.n // (s.m * s.r)), post)
            self._comp_cache[key, i, post] = got
            self._total[key, i, post] = int(got.sum())
        return got

    def reset_counts(self) -> dict[str, LayerCounts]:
        """The counts since the last reset; starts new ones."""
        out, self.counts = self.counts, {}
        return out

    # -- static resources ---------------------------------------------------------------------

    def layers(self) -> list[tuple[str, int, int, int, int]]:
        """Every layer of the three transforms: ``(name, neurons, synapses, components,
        fan_in)`` (synapses = complex weights; components = their nonzero real parts, the
        synaptic operations when every input fires)."""
        g = self.g
        nl, nc = g.n_lp, g.n_cart
        rows: list[tuple[str, int, int, int, int]] = []

        def axis_rows(prefix: str, key: str, size: int) -> None:
            ax = self.axes[key]
            for i, s in enumerate(ax.stages):
                rows.append((f'{prefix} stage {i + 1} (radix {s.r})', size, size * s.r,
                             int(s.comps.sum()) * (size // (s.m * s.r)), s.r))

        rows.append(('S: T taps (pixels → log-polar)', nl, self.T.synapses, self.T.synapses,
                     self.T.fan_in))
        axis_rows('S: fft_θ', 'fθ', nl)
        axis_rows("Λ': ifft_θ", 'iθ', nl)
        rows.append(("Λ': T' taps", nc, self.Tr.synapses, self.Tr.synapses, self.Tr.fan_in))
        axis_rows("Λ': fft_y", 'fy', nc)
        axis_rows("Λ': fft_x", 'fx', nc)
        axis_rows('Λ: ifft_y', 'iy', nc)
        axis_rows('Λ: ifft_x', 'ix', nc)
        rows.append(('Λ: T taps', nl, self.T.synapses, self.T.synapses, self.T.fan_in))
        axis_rows('Λ: fft_θ', 'fθ', nl)
        return rows

    def depth(self) -> tuple[int, int]:
        """Layers on the path of ``Λ'`` and of ``Λ`` (cycles of one pass)."""
        a = self.axes
        rev = len(a['iθ'].stages) + 1 + len(a['fy'].stages) + len(a['fx'].stages)
        fwd = len(a['iy'].stages) + len(a['ix'].stages) + 1 + len(a['fθ'].stages)
        return rev, fwd
