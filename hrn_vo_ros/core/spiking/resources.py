"""Static resources of the sparse spiking network: neurons, synapses, cores, chips, depth.

:func:`sparse_resources` lists every layer of the network of
:class:`~hrn_vo_ros.core.spiking.sparse_engine.SparseSpikingEngine` (transform layers from
:meth:`~hrn_vo_ros.core.spiking.transforms.SparseTransforms.layers`, the bindings, marginals and
the factor cleanups), maps each onto cores of a chip (:class:`~.hardware.ChipLimits`) and checks
the limits. The map update's ``Λ'`` pass reuses the iteration's ``Λ'`` layers (one more pass per
frame: time, not neurons).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hrn_vo_ros.core.hrn.logpolar import Geometry
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.hardware import ChipLimits, LOIHI2
from hrn_vo_ros.core.spiking.transforms import SparseTransforms

#: Cleanup layers of one factor on the critical path (input, similarity, cleanup, state).
CLEANUP_DEPTH = 4


@dataclass(frozen=True, slots=True)
class Layer:
    """One layer: neurons, synapses (complex weights), nonzero weight components, fan-in."""

    name: str
    neurons: int
    synapses: int
    components: int
    fan_in: int


@dataclass(slots=True)
class NetworkResources:
    """The network's layers and totals on one chip type.

    Attributes:
        layers: Every layer. chip: The chip it is mapped to. weight_bits: Of every weight.
        payload_bits: Of the widest spike. depth: Layers on the critical path of one iteration.
        cores_by_layer: Cores of each layer (same order as ``layers``).
    """

    layers: list[Layer]
    chip: ChipLimits
    weight_bits: int
    payload_bits: int
    max_delay: int
    depth: int
    cores_by_layer: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.cores_by_layer = [self.chip.layer_cores(ly.neurons, ly.components,
                                                     self.weight_bits) for ly in self.layers]

    @property
    def neurons(self) -> int:
        """Neurons of the whole network."""
        return sum(ly.neurons for ly in self.layers)

    @property
    def synapses(self) -> int:
        """Synapses (complex weights) of the whole network."""
        return sum(ly.synapses for ly in self.layers)

    @property
    def components(self) -> int:
        """Nonzero real weight components (stored weights)."""
        return sum(ly.components for ly in self.layers)

    @property
    def cores(self) -> int:
        """Neuro-cores, each layer on cores of its own."""
        return sum(self.cores_by_layer)

    @property
    def chips(self) -> int:
        """Chips the cores need."""
        return -(-self.cores // self.chip.cores)

    @property
    def max_fan_in(self) -> int:
        """Largest fan-in of any neuron."""
        return max((ly.fan_in for ly in self.layers), default=0)

    def violations(self) -> list[str]:
        """The chip limits the network exceeds (empty: it fits one chip)."""
        c, out = self.chip, []
        checks = ((self.cores, c.cores, 'neuro-cores'),
                  (self.neurons, c.neurons_per_chip, 'neurons per chip'),
                  (self.components, c.synapses_per_chip, 'synapses per chip'),
                  (self.max_fan_in, c.fan_in_axons, 'fan-in (input axons per core)'),
                  (self.payload_bits, c.payload_bits, 'graded-spike payload bits'),
                  (self.max_delay, c.max_delay, 'synaptic delay steps'))
        for have, limit, what in checks:
            if have > limit:
                out.append(f'{what}: {have} > {limit}')
        return out


def sparse_resources(g: Geometry, tf: SparseTransforms, books: dict[str, tuple[int, int]],
                     cfg: SpikingConfig, *, p_max: bool, chip: ChipLimits = LOIHI2
                     ) -> NetworkResources:
    """The layers of the sparse network for geometry ``g``.

    Args:
        g: The geometry.
        tf: Its transform layers.
        books: Per factor, (vector size n, codebook entries K).
        cfg: Spiking settings (weight and payload bits, delays).
        p_max: The similarity neurons need a K-input max circuit (``exp`` cleanup).
        chip: The chip to map onto.
    """
    nc, nl = g.n_cart, g.n_lp
    wc, hc, nt, nr = g.canvas_width, g.canvas_height, g.n_theta, g.n_rho
    per = 2 if cfg.synapse == 'kick' else 1
    layers = [Layer(*row) for row in tf.layers()]

    def add(name: str, neurons: int, fan_in: int, complex_w: bool = True) -> None:
        syn = neurons * fan_in
        layers.append(Layer(name, neurons, syn, syn * (per if complex_w else 1), fan_in))

    add('map population (sends m̂)', nc, 0)
    add('S_θ ⊙ r̂* (bind)', nl, 2, False)
    add('p̂ ⊙ m̂* (bind)', nc, 2, False)
    add('⊙ v̂*, ⊙ ĥ* (bind)', 2 * nc, 2, False)
    add('h marginal', wc, hc, False)
    add('v marginal', hc, wc, False)
    add('m̂ ⊙ v̂ ⊙ ĥ (bind)', nc, 3, False)
    add('n_ρ w² S_θ ⊙ l̂_θ* (bind)', nl, 2, False)
    add('r marginal', nt, nr, False)
    for k, (n, entries) in books.items():
        add(f'{k} input', n, 1, False)
        add(f'{k} similarity', entries, n)
        if p_max:
            add(f'{k} max circuit', entries, entries, False)
        add(f'{k} cleanup', n, entries)
        add(f'{k} state', n, 2)
    rev, fwd = tf.depth()
    depth = 1 + max(rev + 3, fwd + 2) + CLEANUP_DEPTH + (1 if p_max else 0)
    return NetworkResources(layers, chip, cfg.weight_bits, cfg.widest_payload,
                            cfg.steps_per_cycle - 1 if cfg.synapse == 'delay' else 0, depth)
