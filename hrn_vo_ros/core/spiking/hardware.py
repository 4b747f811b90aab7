"""The neuromorphic chips the spiking network is designed to, with their sources.

Figures and where they come from (what could and could not be checked here is said per figure):

* **Loihi 1** (Davies et al., "Loihi: A Neuromorphic Manycore Processor with On-Chip Learning",
  IEEE Micro 38(1):82-99, 2018, doi:10.1109/MM.2018.112130359): 128 neuro-cores per chip, 1024
  compartments per core (131072 per chip), 4096 input (fan-in) axons per core, 128 KB of
  synaptic memory per core (~130 M synapses per chip at the smallest weights), binary spikes,
  synaptic delays up to 62 steps (6-bit delay field; the brian2_loihi emulator's range).
* **Loihi 2** (Intel Labs, "Taking Neuromorphic Computing to the Next Level with Loihi 2",
  technology brief, 2021; summarised by open-neuromorphic.org's Loihi 2 page): 128 neuro-cores
  and 6 embedded processors per chip, up to 1 M neurons and 120 M synapses per chip (so up to
  8192 neurons per core), 192 KB of memory per core shared by synapses, neuron state and
  routing (the brief's table, as recalled: not re-checked against the brief here), graded spikes
  with integer payloads up to 32 bits. Orchard et al., "Efficient Neuromorphic Signal
  Processing with Loihi 2", IEEE SiPS 2021 (resonate-and-fire neurons, their phase code and the
  graded-spike STFT on Loihi 2) and Shrestha et al., "Efficient Video and Audio Processing with
  Loihi 2", ICASSP 2024 (measured energy/latency of whole networks, not per operation) publish
  no per-operation energies; the per-operation figures used for the estimates are therefore
  Loihi 1's (:class:`~hrn_vo_ros.core.spiking.accounting.LoihiCosts`), an upper bound for a chip
  Intel describes as more efficient per operation.

[design] choices on top of the published limits: 4096 neurons per core (half of Loihi 2's 8192:
a complex resonate-and-fire neuron keeps two 24-bit state variables), each neuron's state takes
8 bytes of the core's memory and each synaptic weight component ``weight_bits + 8`` bits (the
weight and an index/delay field of a sparse synapse format); a layer occupies whole cores of its
own (no two layers share a core), so the core count is an upper bound.
"""

from __future__ import annotations

from dataclasses import dataclass
import math


@dataclass(frozen=True, slots=True)
class ChipLimits:
    """Per-core and per-chip limits of one neuromorphic chip (see the module docstring).

    Attributes:
        name: The chip.
        cores: Neuro-cores per chip.
        neurons_per_core: Neurons the design places on one core ([design] for Loihi 2).
        neurons_per_chip: Published maximum neurons per chip.
        synapses_per_chip: Published maximum synapses per chip.
        memory_per_core: Bytes of core memory for synapses and neuron state.
        fan_in_axons: Distinct input axons per core.
        payload_bits: Largest graded-spike payload (1: binary spikes).
        max_delay: Largest synaptic delay, time steps.
        neuron_bytes: Memory per neuron (state) [design].
        index_bits: Bits per weight component beyond the weight itself [design].
    """

    name: str
    cores: int
    neurons_per_core: int
    neurons_per_chip: int
    synapses_per_chip: int
    memory_per_core: int
    fan_in_axons: int
    payload_bits: int
    max_delay: int
    neuron_bytes: int = 8
    index_bits: int = 8

    def layer_cores(self, neurons: int, components: int, weight_bits: int) -> int:
        """Cores of one layer: enough for its neurons and for its memory (weights and state)."""
        memory = neurons * self.neuron_bytes + components * (weight_bits + self.index_bits) / 8
        return max(1, math.ceil(neurons / self.neurons_per_core),
                   math.ceil(memory / self.memory_per_core))


LOIHI1 = ChipLimits('Loihi 1', cores=128, neurons_per_core=1024, neurons_per_chip=131072,
                    synapses_per_chip=130_000_000, memory_per_core=128 * 1024,
                    fan_in_axons=4096, payload_bits=1, max_delay=62)
LOIHI2 = ChipLimits('Loihi 2', cores=128, neurons_per_core=4096, neurons_per_chip=1_048_576,
                    synapses_per_chip=120_000_000, memory_per_core=192 * 1024,
                    fan_in_axons=4096, payload_bits=32, max_delay=62)

#: Short source line printed with every figure of the report.
SOURCES = ('Loihi 1: Davies et al., IEEE Micro 38(1) 2018; Loihi 2: Intel Labs Loihi 2 '
           'technology brief 2021 (limits as recalled, see core/spiking/hardware.py); per-op '
           'energy/time: Davies et al. 2018 Table 1 (Loihi 1; no per-op Loihi 2 figures are '
           'published: Orchard et al. SiPS 2021, Shrestha et al. ICASSP 2024 give whole-network '
           'measurements)')
