"""Operation accounting of the spiking HRN and its energy/time estimates on Loihi.

Per resonator iteration the emulation counts, per layer, the spikes sent into the layer, the
synaptic operations (one per synapse a spike traverses; two for a complex ``kick`` synapse) and
the neuron updates (every compartment is updated every time step). From these counts:

    E_iter = synops E_syn + neuron_updates E_nu + spikes E_spike                      (energy)
    t_step = (neuron_updates / cores) t_nu + (synops / cores) t_syn  per step  + t_sync (time)

assuming the load is spread evenly over ``cores = ceil(neurons / neurons_per_core)`` neuro-cores
that work in parallel, and one barrier synchronisation per time step.

Per-operation figures: Davies et al., "Loihi: A Neuromorphic Manycore Processor with On-Chip
Learning", IEEE Micro 38(1):82-99, 2018, doi:10.1109/MM.2018.112130359, Table 1 (pre-silicon
SPICE/measurement figures of the 14 nm chip at nominal voltage). **Caveat**: the values below
are as recalled from that table and could only be partly cross-checked here (a third-party
Loihi architecture file citing the same paper, SANA-FE ``arch/loihi.yaml``, agrees on the
2.1 ns within-tile spike latency and the 3.0 pJ / 4.1 ns east-west hop; it lists 4.2 pJ for a
north-south hop). The synaptic-op and neuron-update energies (23.6 pJ, 52/81 pJ) are widely
quoted but were not verified against the paper text in this repository. Treat every energy and
time below as an order-of-magnitude estimate, not a measurement; no published Loihi figures of
the HRN itself were available to compare with.

CPU counts: the float HRN's real floating-point operations (one multiply or add = 1 op; a complex
multiply-add = 8 ops) for the FFT fast path and the dense reference path (``docs/model.md``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
import math

from hrn_vo_ros.core.spiking.synapses import LayerCounts

#: Layer names holding this are the dense transform layers (Λ, Λ', Λ Φ) in :meth:`split`.
TRANSFORM_MARKER = 'Λ'


@dataclass(frozen=True, slots=True)
class LoihiCosts:
    """Per-operation energy (J) and time (s) on Loihi 1 (Davies et al. 2018, Table 1).

    Attributes:
        e_synop: Energy per synaptic spike operation (minimum): 23.6 pJ.
        t_synop: Time per synaptic spike operation (maximum): 3.5 ns.
        e_neuron: Energy per active neuron (compartment) update: 81 pJ (inactive: 52 pJ).
        t_neuron: Time per active neuron update: 8.4 ns (inactive: 5.3 ns).
        e_spike: Energy of a spike within a tile: 1.7 pJ (each mesh hop adds 3.0-4.0 pJ).
        t_sync: Mesh-wide barrier synchronisation per time step: 113-465 ns (1-32 tiles); the
            upper value is used.
        e_neuron_idle: Energy of an inactive compartment update: 52 pJ (a compartment is
            updated every time step whether or not its layer is integrating).
        t_neuron_idle: Time of an inactive compartment update: 5.3 ns.
    """

    e_synop: float = 23.6e-12
    t_synop: float = 3.5e-9
    e_neuron: float = 81e-12
    t_neuron: float = 8.4e-9
    e_spike: float = 1.7e-12
    t_sync: float = 465e-9
    e_neuron_idle: float = 52e-12
    t_neuron_idle: float = 5.3e-9


@dataclass(slots=True)
class IterationAccount:
    """Counts of one or more resonator iterations and their per-iteration Loihi estimate.

    Attributes:
        layers: Counts per layer name, summed over ``iterations``.
        neurons: Neurons (compartments) of the whole network.
        steps: Time steps of one iteration (pipeline depth x steps per cycle).
        cores: Neuro-cores the network needs.
        synapses: Synapses of the whole network.
        iterations: Iterations summed in ``layers`` (the properties are per iteration).
    """

    layers: dict[str, LayerCounts] = field(default_factory=dict)
    neurons: int = 0
    steps: int = 0
    cores: int = 1
    synapses: int = 0
    iterations: int = 0

    def add_iteration(self, other: IterationAccount) -> None:
        """Add the counts of one more iteration (``other`` holds a single one)."""
        for name, c in other.layers.items():
            self.add(name, c)
        self.neurons, self.steps = other.neurons, other.steps
        self.cores, self.synapses = other.cores, other.synapses
        self.iterations += max(other.iterations, 1)

    def _per(self, total: int) -> float:
        return total / max(self.iterations, 1)

    def add(self, name: str, counts: LayerCounts) -> None:
        """Accumulate ``counts`` under ``name``."""
        c = self.layers.setdefault(name, LayerCounts())
        c.spikes_in += counts.spikes_in
        c.synops += counts.synops
        c.neuron_updates += counts.neuron_updates
        c.saturated += counts.saturated

    @property
    def spikes(self) -> float:
        """Spikes sent per iteration (into all layers)."""
        return self._per(sum(c.spikes_in for c in self.layers.values()))

    @property
    def synops(self) -> float:
        """Synaptic operations per iteration."""
        return self._per(sum(c.synops for c in self.layers.values()))

    @property
    def neuron_updates(self) -> float:
        """Neuron (compartment) updates per iteration."""
        return self._per(sum(c.neuron_updates for c in self.layers.values()))

    @property
    def saturated(self) -> float:
        """Neuron-steps per iteration whose integer state hit its bound."""
        return self._per(sum(c.saturated for c in self.layers.values()))

    def energy(self, costs: LoihiCosts | None = None) -> float:
        """Estimated energy of the iteration on Loihi, joules (see the module caveat)."""
        k = costs or LoihiCosts()
        return (self.synops * k.e_synop + self.neuron_updates * k.e_neuron
                + self.spikes * k.e_spike)

    def time(self, costs: LoihiCosts | None = None) -> float:
        """Estimated latency of the iteration on Loihi, seconds (evenly loaded cores)."""
        k = costs or LoihiCosts()
        cores = max(self.cores, 1)
        work = (self.neuron_updates * k.t_neuron + self.synops * k.t_synop) / cores
        return work + self.steps * k.t_sync

    @property
    def idle_updates(self) -> float:
        """Compartment updates per iteration outside the layers' active cycles: every neuron is
        updated at every one of the iteration's ``steps``, the counted (active) updates are only
        the cycle in which its layer integrates."""
        return max(0.0, float(self.neurons) * self.steps - self.neuron_updates)

    def idle_energy(self, costs: LoihiCosts | None = None) -> float:
        """Energy of the idle compartment updates, joules (add to :meth:`energy` for the
        every-compartment-every-step bound)."""
        return self.idle_updates * (costs or LoihiCosts()).e_neuron_idle

    def idle_time(self, costs: LoihiCosts | None = None) -> float:
        """Time of the idle compartment updates on evenly loaded cores, seconds."""
        return self.idle_updates * (costs or LoihiCosts()).t_neuron_idle / max(self.cores, 1)

    def split(self, marker: str = TRANSFORM_MARKER) -> tuple[IterationAccount, IterationAccount]:
        """``(transforms, core)``: the layers whose name holds ``marker`` (the dense Λ/Λ' and
        input layers) and the rest (bindings, marginals, cleanups), as separate accounts."""
        parts = (IterationAccount(iterations=self.iterations), IterationAccount(
            iterations=self.iterations))
        for name, c in self.layers.items():
            parts[0 if marker in name else 1].add(name, c)
        return parts

    def summary(self, costs: LoihiCosts | None = None) -> dict[str, float]:
        """Flat numbers for printing and diagnostics (per iteration)."""
        transforms, core = self.split()
        return {'synops_core': core.synops, 'energy_core_uJ': core.energy(costs) * 1e6,
                'energy_transforms_uJ': transforms.energy(costs) * 1e6,
                'spikes': float(self.spikes), 'synops': float(self.synops),
                'neuron_updates': float(self.neuron_updates), 'neurons': float(self.neurons),
                'cores': float(self.cores), 'steps': float(self.steps),
                'synapses': float(self.synapses),
                'saturated': float(self.saturated), 'energy_uJ': self.energy(costs) * 1e6,
                'time_us': self.time(costs) * 1e6,
                'energy_idle_uJ': self.idle_energy(costs) * 1e6,
                'time_idle_us': self.idle_time(costs) * 1e6}


def mean_account(accounts: Iterable[IterationAccount]) -> dict[str, float]:
    """Mean of :meth:`IterationAccount.summary` over iterations (empty: {})."""
    rows = [a.summary() for a in accounts]
    if not rows:
        return {}
    return {k: sum(r[k] for r in rows) / len(rows) for k in rows[0]}


def cores_for(neurons: int, neurons_per_core: int) -> int:
    """Neuro-cores needed for ``neurons`` compartments."""
    return max(1, math.ceil(neurons / neurons_per_core))


def _fft_ops(n: int) -> float:
    """Real ops of one complex FFT of n points, 5 n log2 n (the usual radix-2 count)."""
    return 5.0 * n * math.log2(max(n, 2))


def cpu_ops(sizes: Mapping[str, int], *, map_update: bool = True) -> dict[str, float]:
    """Real floating-point operations of one float HRN iteration (h, v, r; Model A).

    Args:
        sizes: ``wc``, ``hc`` (canvas), ``n_theta``, ``n_rho`` and the entries ``k_h``, ``k_v``,
            ``k_r`` of the factor codebooks.
        map_update: Include the map update (one more Λ').

    Returns:
        ``{'fast': ops, 'dense': ops}``: the FFT path (Λ = FFT + sparse 4-tap resampling + FFT,
        factorised cleanups) and the dense reference (dense Λ, Λ' and N x K codebooks).
    """
    nc = sizes['wc'] * sizes['hc']
    nl = sizes['n_theta'] * sizes['n_rho']
    n_lambda = 3 + (1 if map_update else 0)          # S = Λ s, p̂ = Λ'(.), l̂ = Λ(.), map: Λ'
    per_lambda = _fft_ops(nc) + _fft_ops(nl) + 4 * 2 * 2 * max(nc, nl)
    binds = 8 * 6.0 * max(nc, nl)                     # ~8 elementwise complex products of N
    small = 0.0
    for axis, k in (('wc', 'k_h'), ('hc', 'k_v'), ('n_theta', 'k_r')):
        small += 2 * 8.0 * sizes[axis] * sizes[k] + 8.0 * nc   # X† a, X p and the marginal
    fast = _fft_ops(nc) + n_lambda * per_lambda + binds + small          # s = fft2(I) first
    dense_lambda = 8.0 * nc * nl
    dense_clean = sum(2 * 8.0 * n * sizes[k] for n, k in ((nc, 'k_h'), (nc, 'k_v'),
                                                          (nl, 'k_r')))
    dense = 8.0 * nc * nc + n_lambda * dense_lambda + binds + dense_clean   # s = Φ I first
    return {'fast': fast, 'dense': dense}
