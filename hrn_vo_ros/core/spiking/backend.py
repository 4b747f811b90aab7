"""The HRN as spiking phasor populations: the float HRN's equations, spiking neurons underneath.

:class:`SpikingHRN` is :class:`~hrn_vo_ros.core.hrn.network.HRN` (same ``step``, readout, map, IMU
prediction) running on :class:`SpikingEngine`, an :class:`~hrn_vo_ros.core.hrn.engine.Engine`
built on :class:`~hrn_vo_ros.core.hrn.fast.FastEngine`. It keeps the fast engine's equations
(Model A, ``docs/model.md``) and replaces its two extension points:

* ``send(name, x)``: the populations S (log-polar input), m (map), p (p̂ = Λ'(S ⊙ r̂*)) and
  l (l̂ = Λ(m̂ ⊙ ĥ ⊙ v̂)) send their vectors as phase-coded spikes (one per neuron and cycle,
  phase on the 2π/T grid, graded payload); the value downstream is what the spikes carry.
  Binding two spike trains is phase addition (and payload product), which the float engine's
  elementwise products of the decoded values compute exactly; marginal sums are the RF
  integration of those kicks in closed form.
* ``update(name, x, a)``: the factor's cleanup and state update run as the spiking layers of
  :class:`~hrn_vo_ros.core.spiking.cleanup.SpikingCleanup` (similarity neurons, threshold ``p``,
  complex synapses back, phasor projection by spike timing, partial self-connection γ), with the
  integer dynamics and quantised weights of ``precision='loihi'``.

This module's :class:`SpikingEngine` is the *dense* form (``spiking.transform: dense``, the
reference); the default sparse form,
:class:`~hrn_vo_ros.core.spiking.sparse_engine.SparseSpikingEngine`, subclasses it and runs
Λ/Λ' as butterfly and log-polar tap layers of phasor neurons. :class:`SpikingHRN` picks the
form (``transform`` says which one runs).

What the dense form does *not* emulate at neuron level ([design], stated for honesty): the
Λ/Λ' transforms and the map update are applied to the spike-coded vectors with float weights
(dense Λ would need N² ≈ 8.5e7 synapses per transform at 128x96, more than a chip holds; they
are counted as dense layers in the accounting); the marginal neurons' integer rounding
(< 2^-state_bits relative) is not emulated; the map's stored value is float (it is sent as
spikes when read).

Accounting (:class:`~hrn_vo_ros.core.spiking.accounting.IterationAccount`) per iteration: the
cleanup layers are counted by the emulation; the binding and Λ layers are counted from the spike
counts of their input populations and their fan-out (binding neurons have fan-in 2-3, dense Λ
layers have fan-out N).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.fast import FastEngine
from hrn_vo_ros.core.hrn.logpolar import Geometry
from hrn_vo_ros.core.hrn.network import HRN
from hrn_vo_ros.core.hrn.shared import cleanup_weights, Floats, Spectrum, state_gamma
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.spiking.accounting import cores_for, IterationAccount
from hrn_vo_ros.core.spiking.cleanup import SpikingCleanup, step_many
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.neurons import encode, NEAREST, Rounding, Spikes
from hrn_vo_ros.core.spiking.synapses import LayerCounts
from hrn_vo_ros.errors import ConfigError

Complex = NDArray[np.complex128]
Real = NDArray[np.float64]

#: Cycles from the input spikes to the new h/v state (S → q → p̂ → u → u⊙v̂* → marginal →
#: similarity → cleanup → state): the latency of one iteration in oscillation cycles.
PIPELINE_DEPTH = 9


class SpikingEngine(FastEngine):
    """The fast (DFT, factorised) engine with spiking populations (see the module docstring).

    Its S, m, p and l populations carry full 2-D spectra, so it runs the general form of the
    float engine's iteration (``direct = False``).

    Args:
        cfg: The resonator configuration (fast path).
        g: Its geometry.
        scfg: Spiking settings.
    """

    direct = False
    single = False      # the dense form is the reference: double-precision spectra

    def __init__(self, cfg: ResonatorConfig, g: Geometry, scfg: SpikingConfig) -> None:
        super().__init__(cfg, g)
        self.scfg = scfg
        same = scfg.nonlinearity == 'same'
        ccfg = cfg.cleanup

        def p_same(a: Real) -> Real:
            return cleanup_weights(a, ccfg)

        self.cleanups = {
            k: SpikingCleanup(self.X[k], scfg, gamma=state_gamma(cfg), name=k,
                              p=p_same if same else None,
                              p_needs_max=same and ccfg.nonlinearity == 'exp')
            for k in self.books}
        self.spikes: dict[str, Spikes] = {}
        self.rounding = NEAREST                 # set_rounding gives the configured one
        self.sent: dict[str, Spikes] = {}
        self.pixels = 0
        self.account = IterationAccount()

    # -- hooks of the float engine ---------------------------------------------------------

    def encode(self, canvas: Floats) -> Spectrum:
        self.pixels = int(np.count_nonzero(canvas))
        return np.asarray(super().encode(canvas), np.complex128)   # general form: double

    def start(self, canvas: Floats, rng: np.random.Generator) -> None:
        super().start(canvas, rng)
        for k, x in self.state.items():
            self._set_state(k, encode(x, self.scfg, fire_threshold=0.0, rounding=self.rounding))

    def set_rounding(self, rng: np.random.Generator) -> None:
        """Every population's payload and spike-step rounding (``SpikingConfig.rounding``,
        ``phase_rounding``; stochastic: from ``rng``, the network's generator), set once when
        the network builds the engine, so that its first frame is coded like the others."""
        self.rounding = Rounding(
            rng if self.scfg.rounding == 'stochastic' else None,
            phase_rng=rng if self.scfg.phase_rounding == 'stochastic' else None)
        for cl in self.cleanups.values():
            cl.rounding = self.rounding

    def send(self, name: str, x: Complex) -> Complex:
        sp = encode(x, self.scfg, rounding=self.rounding)
        self.sent[name] = sp
        return sp.decode()

    def update(self, name: str, x: Complex, a: Complex) -> Complex:
        return self.update_many({name: (x, a)})[name]

    def update_many(self, jobs: dict[str, tuple[Complex, Complex]]) -> dict[str, Complex]:
        """:meth:`update` of several factors, their cleanup layers run as one population each
        (:func:`~hrn_vo_ros.core.spiking.cleanup.step_many`; the same arithmetic)."""
        out: dict[str, Complex] = {}
        names = []
        for name, (x, a) in jobs.items():
            if not a.any():   # no input spikes: no update, as the float engines (blend_state)
                out[name] = x
            else:
                names.append(name)
        results = step_many([(self.cleanups[k], jobs[k][1], self.spikes.get(k)) for k in names])
        for name, (sp, _) in zip(names, results, strict=True):
            cl = self.cleanups[name]
            self.spikes[name] = sp
            # The similarity neurons' states, normalised like the float engine's drive readout.
            if cl.last_input is not None and cl.last_similarity is not None:
                bound = self.col_norm[name] * float(np.linalg.norm(cl.last_input.decode()))
                self.drive[name] = (cl.last_similarity / bound if bound > 0
                                    else np.zeros_like(cl.last_similarity))
            out[name] = sp.decode()
        return out

    def shift(self, name: str, delta: float) -> None:
        # IMU prediction: binding with a fractional power = a phase shift of every neuron,
        # then the state neurons send their (re-quantised) spikes.
        super().shift(name, delta)
        self._set_state(name, encode(self.state[name], self.scfg, fire_threshold=0.0,
                                     rounding=self.rounding))

    def iterate(self, S: Complex) -> None:
        super().iterate(S)
        self.account.add_iteration(self._iteration_account())

    # -- internals -------------------------------------------------------------------------

    def _set_state(self, name: str, sp: Spikes) -> None:
        self.spikes[name] = sp
        self.state[name] = sp.decode()

    def _iteration_account(self) -> IterationAccount:
        """Counts of the iteration that just ran (cleanups measured, the rest by fan-out)."""
        g, steps = self.g, self.scfg.steps_per_cycle
        nc, nl = g.canvas_width * g.canvas_height, g.n_theta * g.n_rho
        wc, hc, nt, nr = g.canvas_width, g.canvas_height, g.n_theta, g.n_rho
        n_s = self.sent['S'].count if 'S' in self.sent else 0
        n_m = self.sent['m'].count if 'm' in self.sent else 0
        n_p = self.sent['p'].count if 'p' in self.sent else 0
        n_l = self.sent['l'].count if 'l' in self.sent else 0
        st = {k: (self.spikes[k].count if k in self.spikes else 0) for k in ('h', 'v', 'r')}
        acc = IterationAccount()

        def layer(name: str, neurons: int, spikes_in: int, synops: int, fan_in: int = 3) -> None:
            # Fan-in above max_fan_in: each neuron becomes a dendritic tree of
            # ceil(fan_in / max_fan_in) compartments (Loihi multi-compartment neurons).
            neurons *= -(-fan_in // self.scfg.max_fan_in)
            acc.add(name, LayerCounts(spikes_in, synops, neurons * steps, 0))
            acc.neurons += neurons

        layer('S = Λ Φ I (pixels → log-polar)', nl, self.pixels, self.pixels * nl, nc)
        layer('S ⊙ r̂* (bind)', nl, n_s + st['r'] * nr, n_s + st['r'] * nr)
        layer("p̂ = Λ'(.) (dense)", nc, n_s, n_s * nc, nl)
        layer('p̂ ⊙ m̂* (bind)', nc, n_p + n_m, n_p + n_m)
        layer('⊙ v̂*, ⊙ ĥ* (bind)', 2 * nc, 2 * n_p + st['v'] * wc + st['h'] * hc,
              2 * n_p + st['v'] * wc + st['h'] * hc)
        layer('h, v marginals', wc + hc, 2 * n_p, 2 * n_p, max(wc, hc))
        layer('m̂ ⊙ ĥ ⊙ v̂ (bind)', nc, n_m + st['h'] * hc + st['v'] * wc,
              n_m + st['h'] * hc + st['v'] * wc)
        layer('l̂ = Λ(.) (dense)', nl, n_m, n_m * nl, nc)
        layer('S ⊙ l̂* (bind)', nl, n_s + n_l, n_s + n_l)
        layer('r marginal', nt, n_l, n_l, nr)
        for k, cl in self.cleanups.items():
            counts = cl.reset_counts()
            for lname, c in counts.items():
                acc.add(f'{k} {lname}', c)
            # input/state/cleanup neurons: n each; similarity: K (+1 inhibitor or K max).
            acc.neurons += 3 * cl.size + cl.entries + 1
        acc.steps = PIPELINE_DEPTH * steps
        acc.cores = cores_for(acc.neurons, self.scfg.neurons_per_core)
        # Dense Λ Φ (pixels → S), Λ', Λ and the map's Λ'; the cleanups' X^H and X.
        acc.synapses = 4 * nc * nl + sum(2 * cl.size * cl.entries
                                         for cl in self.cleanups.values())
        return acc


class SpikingHRN(HRN):
    """The HRN with spiking phasor populations (same API as :class:`HRN`).

    Args:
        cfg: Resonator configuration; the spiking backend needs ``path='fast'`` (DFT codebooks,
            factorised populations).
        rng: Random initial states.
        spiking: Spiking settings (default :class:`SpikingConfig`).

    Raises:
        ConfigError: for ``path='dense'`` or invalid spiking settings.
    """

    _spiking_engine: SpikingEngine

    def __init__(self, cfg: ResonatorConfig | None = None, *, rng: np.random.Generator,
                 spiking: SpikingConfig | None = None, **kwargs: Any) -> None:
        self.spiking = spiking if spiking is not None else SpikingConfig()
        self.last_account: IterationAccount | None = None
        self.transform = self.spiking.transform     # the form that runs (set by the engine)
        if (cfg if cfg is not None else ResonatorConfig()).path != 'fast':
            raise ConfigError('the spiking backend needs path: fast (DFT codebooks): its neuron '
                              'populations are the factorised ones; set path to fast')
        super().__init__(cfg, rng=rng, engine=self._build_engine, **kwargs)

    def _build_engine(self, cfg: ResonatorConfig, g: Geometry) -> SpikingEngine:
        """The network's engine (``HRN(engine=...)``), kept typed for the spike outputs: the
        sparse form where it runs (``transform``), else the dense one."""
        from hrn_vo_ros.core.spiking.sparse_engine import sparse_supported, SparseSpikingEngine
        if self.spiking.transform == 'sparse' and sparse_supported(cfg):
            self._spiking_engine = SparseSpikingEngine(cfg, g, self.spiking)
            self.transform = 'sparse'
        else:
            self._spiking_engine = SpikingEngine(cfg, g, self.spiking)
            self.transform = 'dense'
        self._spiking_engine.set_rounding(self.rng)     # (HRN sets rng before the engine)
        return self._spiking_engine

    def step(self, image: NDArray[Any], t_ns: int, *,
             gyro_delta: NDArray[Any] | None = None) -> Estimate:
        """One event frame (see :meth:`HRN.step`); also records the frame's accounting."""
        eng = self._spiking_engine
        eng.account = IterationAccount()
        est = super().step(image, t_ns, gyro_delta=gyro_delta)
        if eng.account.iterations:
            if est.map_updated and self.transform == 'dense':
                g, steps = self.geometry, self.spiking.steps_per_cycle
                nc = g.canvas_width * g.canvas_height
                n_s = eng.sent['S'].count if 'S' in eng.sent else 0
                parts = -(-g.n_theta * g.n_rho // self.spiking.max_fan_in)   # dendritic split
                eng.account.add("map: Λ'(S ⊙ r^-r) ⊙ h^-h ⊙ v^-v",
                                LayerCounts(n_s, n_s * nc + 2 * nc, (1 + parts) * nc * steps, 0))
            self.last_account = eng.account
        return est

    def raster(self) -> NDArray[np.uint8]:
        """Spike raster of the last cycle: rows = neurons, columns = time steps.

        Rows, per factor (h, v, r [, z]): the factor's input (marginal) neurons, then its state
        neurons; a pixel is the spike's payload scaled to 1..255 (0: no spike at that step).

        Shapes:
            returns (rows, steps_per_cycle) uint8.
        """
        eng = self._spiking_engine
        steps = self.spiking.steps_per_cycle
        blocks = []
        for k in self.factors:
            cl = eng.cleanups[k]
            for sp in (cl.last_input, eng.spikes.get(k)):
                img = np.zeros((cl.size, steps), np.uint8)
                if sp is not None and sp.g.size:
                    top = max(int(sp.g.max()), 1)
                    level = np.where(sp.g > 0, 1 + (254 * sp.g) // top, 0).astype(np.uint8)
                    img[np.arange(cl.size), sp.t] = level
                blocks.append(img)
        return np.concatenate(blocks, axis=0)

    def account_summary(self) -> dict[str, float]:
        """Per-iteration counts and Loihi estimates of the last frame ({} before the first)."""
        return {} if self.last_account is None else self.last_account.summary()
