"""The spiking engine with sparse transforms (``spiking.transform: sparse``, the default).

:class:`SparseSpikingEngine` runs the float fast engine's *direct form* (``core/hrn/fast.py``:
the frame as its θ-spectrum ``S_θ``, ``Λ'(S ⊙ r̂*)`` from one inverse DFT along θ, the roll
marginal by Parseval along ρ) with every transform as phasor-neuron layers
(:class:`~hrn_vo_ros.core.spiking.transforms.SparseTransforms`): the frame's ``S_θ``, ``p̂`` and
``l̂_θ`` of every iteration and the map update's target are what the last layer's spikes carry.
The bindings (phase addition, payload product), marginals and the factor cleanups are those of
the dense spiking form (:class:`~hrn_vo_ros.core.spiking.backend.SpikingEngine`), whose cleanup
layers it reuses.

Not spiking ([design], as in the dense form): the map's stored value (float; the map population
sends it as spikes every iteration), its first value ``m̂(0) = fft2(canvas)`` and the
re-localisation's global search while lost (``FastEngine.relocalise``, float: an occasional
search over 24 rolls, not part of the per-iteration network).

Needs h, v, r without whitening (the direct form); a configuration with a scale factor or
``cleanup.whiten`` runs the dense form (:func:`~hrn_vo_ros.core.spiking.backend.SpikingHRN`
says which form runs in ``transform``).
"""

from __future__ import annotations

import numpy as np

from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.logpolar import Geometry
from hrn_vo_ros.core.hrn.shared import Floats, Spectrum
from hrn_vo_ros.core.spiking.accounting import IterationAccount
from hrn_vo_ros.core.spiking.backend import Complex, SpikingEngine
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.neurons import encode
from hrn_vo_ros.core.spiking.resources import NetworkResources, sparse_resources
from hrn_vo_ros.core.spiking.synapses import LayerCounts
from hrn_vo_ros.core.spiking.transforms import C64, SparseTransforms


def sparse_supported(cfg: ResonatorConfig) -> bool:
    """Whether the sparse form can run ``cfg`` (no scale factor, no whitening)."""
    return not cfg.scale.enabled and not cfg.cleanup.whiten


class SparseSpikingEngine(SpikingEngine):
    """The direct form of the fast engine on sparse spiking transforms (module docstring).

    Args:
        cfg: The resonator configuration (fast path, no scale factor, no whitening).
        g: Its geometry.
        scfg: Spiking settings.
    """

    direct = True

    def __init__(self, cfg: ResonatorConfig, g: Geometry, scfg: SpikingConfig) -> None:
        super().__init__(cfg, g, scfg)
        self.tf = SparseTransforms(g, scfg)
        self._S: C64 = np.zeros((g.n_rho, g.n_theta), np.complex64)
        self._S_w: C64 = self._S
        self._m_src: Spectrum | None = None
        self._m_sp: C64 = np.zeros((g.canvas_height, g.canvas_width), np.complex64)
        self._n_m = 0
        self._synced: dict[str, Complex] = {}
        self.resources: NetworkResources = sparse_resources(
            g, self.tf, {k: (cl.size, cl.entries) for k, cl in self.cleanups.items()},
            scfg, p_max=scfg.nonlinearity == 'same' and cfg.cleanup.nonlinearity == 'exp')

    # -- hooks of the float engine ---------------------------------------------------------

    def encode(self, canvas: Floats) -> C64:
        """``S_θ`` as the frame's spikes carry it (also the ring-weighted ``n_ρ w² S_θ``)."""
        self.pixels = int(np.count_nonzero(canvas))
        S = self.tf.frame(canvas)
        self._S = S
        self._S_w = S * self._roll_rows
        return S

    def start(self, canvas: Floats, rng: np.random.Generator) -> None:
        super().start(canvas, rng)
        self._synced = dict(self.state)

    def set_rounding(self, rng: np.random.Generator) -> None:
        super().set_rounding(rng)
        self.tf.code.rounding = self.rounding

    def update_many(self, jobs: dict[str, tuple[Complex, Complex]]) -> dict[str, Complex]:
        # a state set outside the cleanups (restored by the network's hold or IMU gate) is
        # what the state neurons send next: re-encode it
        for name, (x, _) in jobs.items():
            if self._synced.get(name) is not x:
                self._set_state(name, encode(np.asarray(x, np.complex128), self.scfg,
                                             fire_threshold=0.0, rounding=self.rounding))
        out = super().update_many(jobs)
        self._synced.update(out)
        return out

    def shift(self, name: str, delta: float) -> None:
        super().shift(name, delta)
        self._synced[name] = self.state[name]

    def _map_spikes(self) -> C64:
        """The map population's spikes (re-encoded when the map changed)."""
        if self._m_src is not self.m:
            self._m_src = self.m
            self.tf.code.label = 'map population'
            self._m_sp = self.tf.code.fire(np.asarray(self.m, np.complex64))
            self._n_m = self.tf.code.last_count
        return self._m_sp

    def iterate(self, S: Spectrum) -> None:
        st = self.state
        h, v, r = st['h'], st['v'], st['r']
        hs, vs, rs = (x.astype(np.complex64) for x in (h, v, r))
        m = self._map_spikes()
        u = self.tf.reverse(self._S * rs.conj()[None, :])       # p̂ = Λ'(S_θ ⊙ r̂*)
        u *= m.conj()                                            # p̂ ⊙ m̂*
        lt = self.tf.forward(m * vs[:, None] * hs[None, :])     # l̂_θ = Λ(m̂ ⊙ v̂ ⊙ ĥ)
        np.conjugate(lt, out=lt)
        lt *= self._S_w                                          # n_ρ w² S_θ ⊙ l̂_θ*
        a_r = lt.sum(axis=0).astype(np.complex128)
        a_h = (u * vs.conj()[:, None]).sum(axis=0).astype(np.complex128)
        a_v = (u * hs.conj()[None, :]).sum(axis=1).astype(np.complex128)
        self.inputs.update(h=a_h, v=a_v, r=a_r)
        st.update(self.update_many({'h': (h, a_h), 'v': (v, a_v), 'r': (r, a_r)}))
        self.account.add_iteration(self._iteration_account())

    def map_target(self, S: Spectrum, point: dict[str, float]) -> Spectrum:
        """The frame moved into the map at ``point`` through the spiking ``Λ'`` layers."""
        jp = self._jphases
        rq = np.exp(jp['r'] * float(-point['r'])).astype(np.complex64)
        t = self.tf.reverse(self._S * rq[None, :], prefix="map: Λ'")
        t *= np.exp(jp['v'] * float(-point['v'])).astype(np.complex64)[:, None]
        t *= np.exp(jp['h'] * float(-point['h'])).astype(np.complex64)[None, :]
        return t

    def update_map(self, S: Complex, point: dict[str, float], mu1: float, mu2: float,
                   target: Spectrum | None = None) -> None:
        super().update_map(S, point, mu1, mu2,
                           self.map_target(S, point) if target is None else target)

    # -- accounting ------------------------------------------------------------------------

    def _iteration_account(self) -> IterationAccount:
        """Counts of the iteration that just ran: the transform layers as measured (and the
        frame's own layers, S and the map targets, which the per-iteration figures spread over
        the frame's iterations), bindings and marginals from their spike counts, cleanups as
        measured."""
        g, steps = self.g, self.scfg.steps_per_cycle
        nc, nl = g.n_cart, g.n_lp
        wc, hc, nt, nr = g.canvas_width, g.canvas_height, g.n_theta, g.n_rho
        n_s = int(np.count_nonzero(self._S))
        n_m = self._n_m
        st = {k: (self.spikes[k].count if k in self.spikes else 0) for k in ('h', 'v', 'r')}
        acc = IterationAccount()
        for name, c in self.tf.reset_counts().items():
            acc.add(name, c)

        def layer(name: str, neurons: int, spikes_in: int, synops: int) -> None:
            acc.add(name, LayerCounts(spikes_in, synops, neurons * steps, 0))

        layer('S_θ ⊙ r̂* (bind)', nl, n_s + st['r'] * nr, n_s + st['r'] * nr)
        layer('p̂ ⊙ m̂* (bind)', nc, nc + n_m, nc + n_m)
        layer('⊙ v̂*, ⊙ ĥ* (bind)', 2 * nc, 2 * nc + st['v'] * wc + st['h'] * hc,
              2 * nc + st['v'] * wc + st['h'] * hc)
        layer('h, v marginals', wc + hc, 2 * nc, 2 * nc)
        layer('m̂ ⊙ ĥ ⊙ v̂ (bind)', nc, n_m + st['h'] * hc + st['v'] * wc,
              n_m + st['h'] * hc + st['v'] * wc)
        layer('n_ρ w² S_θ ⊙ l̂_θ* (bind)', nl, n_s + nl, n_s + nl)
        layer('r marginal', nt, nl, nl)
        for k, cl in self.cleanups.items():
            for lname, c in cl.reset_counts().items():
                acc.add(f'{k} {lname}', c)
        res = self.resources
        acc.neurons, acc.synapses, acc.cores = res.neurons, res.synapses, res.cores
        acc.steps = res.depth * steps
        return acc
