"""The resonator cleanup ``x <- (1-gamma) x + gamma f(X p(Re(X^H u))))`` as spiking layers.

Layers of one factor (the HRN cleanup mapped onto phasor neurons), each one oscillation cycle:

1. **input** phasor neurons: the (marginalised) unbound input ``u`` as phase-coded spikes with
   graded payloads (:func:`~hrn_vo_ros.core.spiking.neurons.encode`);
2. **similarity** neurons, one per codebook entry ``k``: RF neurons driven through the complex
   synapses ``conj(X)^T``; their end-of-cycle real part is ``a_k = Re(X^H u)_k``. An inhibitory
   input ``theta * sum_j |u_j|`` (one integrator neuron that sums all input payloads, fan-out K)
   sets the threshold, and the neuron sends the graded spike ``p(a_k) = ReLU(a_k - theta
   sum_j |u_j|)`` at the reference phase: the ReLU-like ``p`` of the seed's Eq. 4;
3. **cleanup** neurons, one per vector element: RF neurons driven through the complex synapses
   ``X``; each fires a *unit* spike at the phase of ``X p(a)``: the phasor projection ``f``;
4. **state** neurons: RF neurons with a partial self-connection ``1 - gamma`` (their own previous
   spike) and the cleanup spike with weight ``gamma``: ``x <- (1-gamma) x + gamma f(.)``. Their
   graded spike is the new state.

With ``precision='loihi'`` every layer runs the integer (RF-int) dynamics with quantised weights
(``gamma`` and ``1 - gamma`` share one exponent); with ``'float'`` the same spikes are integrated
in float.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
import functools

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.neurons import (
    encode_many,
    NEAREST,
    rf_cycle_populations,
    Rounding,
    Spikes,
)
from hrn_vo_ros.core.spiking.synapses import (
    ComplexSynapses,
    drive_many,
    LayerCounts,
    scale_kicks_float,
)

Complex = NDArray[np.complex128]
Real = NDArray[np.float64]
Int = NDArray[np.int64]

LAYERS = ('input', 'similarity', 'threshold', 'cleanup', 'state')


@dataclass(slots=True, eq=False)
class SpikingCleanup:
    """One factor's cleanup and state update as spiking phasor layers.

    Args:
        codebook: Codebook matrix ``X``, one column per entry (compact form for DFT factors:
            the element axis is the factor's own frequency axis).
        cfg: Spiking settings.
        gamma: Update speed of the state, in (0, 1].
        threshold: ``theta`` of ``p`` (default ``cfg.threshold``).
        name: Factor name for the accounting.
        p: The similarity neurons' output function of their state ``a`` (default: the ReLU
            threshold above). A callable that needs ``max(a)`` stands for a K-input max
            circuit, counted as one more layer of K neurons.
        p_needs_max: Whether ``p`` uses the max over entries (accounting only).

    Shapes:
        codebook: (n, K).
    """

    codebook: Complex
    cfg: SpikingConfig
    gamma: float
    threshold: float | None = None
    name: str = 'x'
    p: Callable[[Real], Real] | None = None
    p_needs_max: bool = False
    counts: dict[str, LayerCounts] = field(init=False)
    last_input: Spikes | None = field(init=False, default=None)
    last_similarity: Real | None = field(init=False, default=None)
    _sim: ComplexSynapses = field(init=False)
    _out: ComplexSynapses = field(init=False)
    _mix: ComplexSynapses = field(init=False)
    _theta: float = field(init=False)
    _dc: NDArray[np.intp] = field(init=False)
    rounding: Rounding = field(init=False, default=NEAREST)   # the engine's (set_rounding)

    def __post_init__(self) -> None:
        x = np.asarray(self.codebook, dtype=np.complex128)
        # DC neurons: elements whose codebook row is the same for every entry (a DFT book's
        # frequency 0) add the same to every similarity; in a spectrum they dwarf the others
        # (10^3-10^4 x the median element), so they send on a wider payload instead of setting
        # the unit of the whole population (SpikingConfig.dc_payload_bits)
        same = np.all(np.abs(x - x[:, :1]) <= 1e-9 * np.abs(x).max(initial=1.0), axis=1)
        self._dc = np.flatnonzero(same) if self.cfg.dc_wide else np.zeros(0, np.intp)
        tops = np.full(x.shape[0], (1 << self.cfg.payload_bits) - 1, np.int64)
        tops[self._dc] = (1 << self.cfg.dc_payload_bits) - 1
        self._sim = ComplexSynapses(x.conj().T, self.cfg, name=f'{self.name}.similarity',
                                    tops=tops)
        self._out = ComplexSynapses(x, self.cfg, name=f'{self.name}.cleanup')
        # Self-connection and input weight of each state neuron (one shared exponent).
        self._mix = ComplexSynapses(np.array([[1.0 - self.gamma, self.gamma]]), self.cfg,
                                    name=f'{self.name}.state')
        self._theta = self.cfg.threshold if self.threshold is None else self.threshold
        self.counts = {k: LayerCounts() for k in LAYERS}

    @property
    def size(self) -> int:
        """Number of vector elements ``n``."""
        return int(self.codebook.shape[0])

    @property
    def entries(self) -> int:
        """Number of codebook entries ``K``."""
        return int(self.codebook.shape[1])

    def similarity(self, u: Spikes) -> Real:
        """``p(a)`` of the similarity neurons for input spikes ``u`` (layers 2 and the inhibitor).

        Shapes:
            u: (n,); returns (K,) float64 (>= 0 for the ReLU).
        """
        return self._p(u, self._sim.drive(u, self.counts['similarity']).real)

    def _p(self, u: Spikes, a: Real) -> Real:
        """``p`` of the similarity neurons' states ``a`` (and the inhibitor's counts)."""
        self.last_similarity = a
        c = self.counts['threshold']
        if self.p is not None:
            if self.p_needs_max:                 # K-input max (WTA) circuit: K neurons
                c.spikes_in += self.entries
                c.synops += self.entries * self.entries
                c.neuron_updates += self.entries * self.cfg.steps_per_cycle
            return np.asarray(self.p(a), dtype=np.float64)   # a negative p: phase pi
        mass = float(np.ldexp(u.g.sum(dtype=np.float64), u.exp))
        c.spikes_in += u.count
        c.synops += u.count + self.entries       # payloads in, one inhibitory spike out to K
        c.neuron_updates += self.cfg.steps_per_cycle
        return np.maximum(a - self._theta * mass, 0.0)

    def step(self, u: Complex, state: Spikes | None) -> tuple[Spikes, Real]:
        """One resonator iteration of this factor.

        Args:
            u: The unbound input of the factor (end-of-cycle state of its input neurons).
            state: The state neurons' previous spikes (``None`` at the first iteration: the
                state becomes the cleanup output).

        Returns:
            ``(state, p)``: the new state spikes and the similarity neurons' ``p(a)``.

        Shapes:
            u: (n,); state: (n,); p: (K,).
        """
        return step_many([(self, u, state)])[0]

    def _input(self, u_sp: Spikes) -> Spikes:
        """Layer 1: the input neurons' spikes ``u_sp`` (``encode`` of the input, the DC neurons
        ``_dc`` on the wider payload): recorded and counted."""
        self.last_input = u_sp
        ci = self.counts['input']
        ci.spikes_in += u_sp.count
        ci.neuron_updates += self.size * self.cfg.steps_per_cycle
        return u_sp

    def _pairs(self, drive: Complex, steps: Int, state: Spikes | None) -> Spikes:
        """Layer 3's unit spikes at the phase of ``X p(a)`` (the phasor projection f; ``steps``:
        the spike steps of ``drive``), paired with each state neuron's own previous spike: the
        state layer's two inputs."""
        cfg = self.cfg
        # (a constant full-scale payload 2^B - 1 in units of 2^-B, i.e. ~1)
        top = (1 << cfg.payload_bits) - 1
        unit_g = np.where(np.abs(drive) > 0.0, np.int64(top), np.int64(0))
        f_sp = Spikes(steps, unit_g, -cfg.payload_bits, cfg.steps_per_cycle)
        if state is None:
            prev_t, prev_g, prev_exp = f_sp.t, f_sp.g, f_sp.exp
        else:
            prev_t, prev_g, prev_exp = state.t, state.g, state.exp
        pair_t = np.stack([prev_t, f_sp.t], axis=1)                        # (n, 2)
        # Bring both inputs to the same payload unit before the shared 2-input synapse.
        e = max(prev_exp, f_sp.exp)
        prev_scaled = np.rint(np.ldexp(prev_g.astype(np.float64), prev_exp - e)).astype(np.int64)
        f_scaled = np.rint(np.ldexp(f_sp.g.astype(np.float64), f_sp.exp - e)).astype(np.int64)
        pair_g = np.stack([prev_scaled, f_scaled], axis=1)
        return Spikes(pair_t, pair_g, e, cfg.steps_per_cycle)

    def _mix_kicks(self, pairs: Spikes, out: Real | None) -> None:
        """Counts of the state layer; its integer kicks written into ``out`` (zeros on entry,
        the (T, 2, n) layout of :func:`~hrn_vo_ros.core.spiking.neurons.rf_cycle_kicks`; None
        in float precision)."""
        n = pairs.t.shape[0]
        c = self.counts['state']
        c.spikes_in += int(np.count_nonzero(pairs.g))
        c.synops += int(np.count_nonzero(pairs.g)) * (2 if self.cfg.synapse == 'kick' else 1)
        c.neuron_updates += n * self.cfg.steps_per_cycle
        if out is None:
            return
        # The closed form of (RF) per neuron equals the step loop for two inputs except for
        # the fixed-point rotation; the loop runs on all n neurons at once. Each input adds
        # one kick per neuron (distinct (step, neuron) pairs per input: a fancy-index add).
        steps = self.cfg.steps_per_cycle
        q = self._mix._q
        assert q is not None
        rows = np.arange(n)
        shift = self._mix._shift
        # a left shift is exact per kick (integers below 2^53): applied to each before the sum
        unit = 2.0 ** shift if shift >= 0 else 1.0
        for j in range(2):
            if self.cfg.synapse == 'kick':
                out[pairs.t[:, j], 0, rows] += (q.re[0, j] * pairs.g[:, j]) * unit
                out[pairs.t[:, j], 1, rows] += (q.im[0, j] * pairs.g[:, j]) * unit
            else:
                assert self._mix._delay is not None
                arrive = (pairs.t[:, j] + self._mix._delay[0, j]) % steps
                out[arrive, 0, rows] += (q.re[0, j] * pairs.g[:, j]) * unit
        if shift < 0:
            scale_kicks_float(out, shift)

    def _mix_value(self, pairs: Spikes, ri: tuple[Int, Int] | None) -> Complex:
        """The state neurons' end-of-cycle value (float closed form, or the integer state)."""
        if ri is None:
            return np.asarray(pairs.decode() @ self._mix.effective[0], dtype=np.complex128)
        q = self._mix._q
        assert q is not None
        re, im = ri
        return np.asarray((re + 1j * im) * 2.0**(q.exp + pairs.exp - self._mix._shift),
                          dtype=np.complex128)

    def reset_counts(self) -> dict[str, LayerCounts]:
        """Return the counts since the last reset and start new ones."""
        out = self.counts
        self.counts = {k: LayerCounts() for k in LAYERS}
        return out


def step_many(items: list[tuple[SpikingCleanup, Complex, Spikes | None]]
              ) -> list[tuple[Spikes, Real]]:
    """:meth:`SpikingCleanup.step` of several factors (one shared configuration) in one pass:
    each layer's integer dynamics run once for the neurons of all factors (the same arithmetic
    per neuron; the factors' cleanups are independent within an iteration).

    Returns:
        Per item, ``(state, p)`` as :meth:`SpikingCleanup.step`.
    """
    if not items:
        return []
    cfg = items[0][0].cfg
    rnd = items[0][0].rounding
    u_sps = [cl._input(sp) for (cl, _, _), sp in zip(items, encode_many(
        [u for _, u, _ in items], cfg, wides=[cl._dc for cl, _, _ in items],
        wide_bits=cfg.dc_payload_bits, rounding=rnd), strict=True)]
    sims = drive_many([(cl._sim, u_sp, cl.counts['similarity'])
                       for (cl, _, _), u_sp in zip(items, u_sps, strict=True)])
    ps = [cl._p(u_sp, a.real) for (cl, _, _), u_sp, a in zip(items, u_sps, sims, strict=True)]
    # Similarity neurons fire at the reference phase (t = 0) with graded payload p.
    p_sps = encode_many([p.astype(np.complex128) for p in ps], cfg, fire_threshold=0.0,
                        rounding=rnd)
    drives = drive_many([(cl._out, p_sp, cl.counts['cleanup'])
                         for (cl, _, _), p_sp in zip(items, p_sps, strict=True)])
    # the cleanup neurons' spike steps (one pass for all factors' drives)
    sizes = [d.size for d in drives]
    steps = np.split(rnd.step(np.concatenate(drives), cfg.steps_per_cycle),
                     np.cumsum(sizes)[:-1])
    pairs = [cl._pairs(d, t, st)
             for (cl, _, st), d, t in zip(items, drives, steps, strict=True)]
    states: list[tuple[Int, Int] | None] = [None] * len(items)
    if not cfg.quantised:
        for (cl, _, _), pr in zip(items, pairs, strict=True):
            cl._mix_kicks(pr, None)
    else:
        per_population, sat = rf_cycle_populations(
            [functools.partial(cl._mix_kicks, pr) for (cl, _, _), pr in zip(items, pairs,
                                                                              strict=True)],
            [cl.size for cl, _, _ in items], cfg)
        items[0][0].counts['state'].saturated += sat
        states[:] = per_population
    values = [cl._mix_value(pr, ri) for (cl, _, _), pr, ri in zip(items, pairs, states,
                                                                      strict=True)]
    return list(zip(encode_many(values, cfg, fire_threshold=0.0, rounding=rnd), ps,
                    strict=True))
