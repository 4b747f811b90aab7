"""Configuration of the spiking phasor emulation and of its Loihi constraints.

Every limit below names its source. Three kinds of source are used:

* **Davies et al. 2018**: M. Davies et al., "Loihi: A Neuromorphic Manycore Processor with
  On-Chip Learning", IEEE Micro 38(1):82-99, 2018, doi:10.1109/MM.2018.112130359 (Loihi 1: 24-bit
  signed compartment voltage, 8-bit-mantissa synaptic weights with a per-connection exponent,
  per-synapse delays, 1024 compartments and 4096 input axons per core, 128 cores per chip).
* **Lava and brian2_loihi**: the Lava resonate-and-fire model
  (``lava-nc/lava`` ``proc/rf``: 12-bit sin/cos decay constants, 24-bit state) and the
  brian2_loihi emulator (delays 0..62 steps, weights -256..254 in mixed-sign mode, precision set
  by ``num_weight_bits``, scale 2**(6 + wgt_exp) with wgt_exp in [-8, 7]).
* **[design]**: choices of this emulation that no hardware source fixes (stated as such).

``precision='float'`` keeps the same spike times (phases on the 2*pi/T grid, the same graded
payloads) but uses float weights and float neuron state, so that timing error and quantisation
error can be told apart: ``'loihi'`` minus ``'float'`` is the quantisation error, ``'float'``
minus the float HRN is the timing (and payload) error.
"""

from __future__ import annotations

from dataclasses import dataclass

from hrn_vo_ros.core.configbase import param, validate
from hrn_vo_ros.errors import ConfigError

#: Largest synaptic delay of a Loihi 1 synapse in time steps (brian2_loihi).
LOIHI_MAX_DELAY = 62


@dataclass(frozen=True, slots=True)
class SpikingConfig:
    """Spiking phasor network settings (see the module docstring for the sources).

    A phase phi is sent as one spike per oscillation cycle of ``steps_per_cycle`` = T time steps,
    at step ``round(phi * T / 2 pi) mod T`` (Frady & Sommer, PNAS 2019). Phase-coded synapses need
    delays up to T - 1 steps, so T - 1 <= ``max_delay`` (<= 62 on Loihi 1).
    """

    transform: str = param(
        'sparse', "Λ/Λ': sparse = butterfly DFT stages and <= 4-tap log-polar resampling as "
        'phasor-neuron layers (N log N synapses); dense = float transforms of the spike-coded '
        'vectors, counted as dense N x N layers (the reference)',
        choices=('sparse', 'dense'), read_only=True)
    max_radix: int = param(
        4, 'largest radix of the sparse butterfly stages (2: more, smaller layers)', lo=2, hi=8,
        read_only=True)
    precision: str = param(
        'loihi', 'loihi: integer state, quantised weights; float: same spikes, float arithmetic',
        choices=('loihi', 'float'))
    steps_per_cycle: int = param(
        32, 'T: time steps per oscillation cycle (phase resolution 2*pi/T); T-1 <= max_delay',
        lo=4, read_only=True)
    max_delay: int = param(
        LOIHI_MAX_DELAY, 'largest synaptic delay in time steps (Loihi 1: 62)', lo=1,
        hi=LOIHI_MAX_DELAY, read_only=True)
    synapse: str = param(
        'kick', 'complex synapse: kick = complex weight into a resonate-and-fire neuron '
        '(weight quantisation), delay = phase as a synaptic delay (phase on the 2*pi/T grid)',
        choices=('kick', 'delay'), read_only=True)
    weight_bits: int = param(
        8, 'bits of the signed weight mantissa (Loihi: 8; num_weight_bits 1..8)', lo=2, hi=8,
        read_only=True)
    payload_bits: int = param(
        8, 'bits of a graded spike payload (amplitude); 1 = binary spikes (Loihi 1)', lo=1,
        hi=24, read_only=True)
    dc_payload_bits: int = param(
        12, "payload bits of a cleanup input's DC neuron (the element that adds the same to "
        'every similarity); the rest of the population keeps payload_bits in a finer unit '
        '(<= payload_bits: one unit for all, sized by the DC term)', lo=1, hi=24, read_only=True)
    transform_payload_bits: int = param(
        8, "payload bits of the sparse transforms' neurons (the frame's log-polar spectrum, "
        "the stages of Λ' and Λ, and the map population that feeds them); a 2-D spectrum's DC "
        'sets the unit, so on 8 bits a fifth to a third of the rest round to silence on dense '
        'frames (12 measured: docs/spiking.md); binary when payload_bits is 1', lo=1, hi=24,
        read_only=True)
    state_bits: int = param(
        24, 'bits of the signed integer neuron state (Loihi compartment voltage: 24)', lo=12,
        hi=32, read_only=True)
    decay_bits: int = param(
        12, 'fractional bits of the fixed-point rotation (sin/cos) constants (Lava RF: 12)',
        lo=6, hi=16, read_only=True)
    rounding: str = param(
        'nearest', 'payload magnitudes rounded to the nearest unit, or stochastic: up with the '
        'probability of the fraction, from a pseudo-random number per neuron and cycle '
        "(dithered; unbiased; the network's rng; Loihi's compartments have a noise source)",
        choices=('nearest', 'stochastic'), read_only=True)
    phase_rounding: str = param(
        'nearest', 'spike steps rounded to the nearest step, or stochastic: round(arg z T / '
        "2 pi) becomes floor(arg z T / 2 pi + u), u uniform in [0, 1) per neuron and cycle from "
        "the network's rng (dithered spike times: unbiased, so a phase change below half a step "
        'still moves what the cleanup and state neurons send; a noise source on the neuron)',
        choices=('nearest', 'stochastic'), read_only=True)
    nonlinearity: str = param(
        'same', "p of the similarity neurons: same = the float backend's p on their state "
        '(exp needs a K-input max circuit), relu = ReLU(a - threshold * input mass)',
        choices=('same', 'relu'), read_only=True)
    threshold: float = param(
        0.0, 'theta of the relu similarity neurons, as a fraction of the input mass sum|u|',
        lo=-1.0, hi=1.0)
    fire_threshold: float = param(
        0.0, 'phasor neurons stay silent when |z| < fire_threshold * mean |z| (TPAM threshold)',
        lo=0.0, hi=1.0)
    max_fan_in: int = param(
        4096, 'largest number of synapses into one neuron (Loihi 1: 4096 input axons per '
        'core)', lo=2, read_only=True)
    neurons_per_core: int = param(
        1024, 'compartments per neuro-core for the time estimate (Loihi 1: 1024)', lo=1,
        read_only=True)

    def __post_init__(self) -> None:
        """Check ranges and the delay limit."""
        validate(self)
        if self.steps_per_cycle - 1 > self.max_delay:
            msg = (f'SpikingConfig.steps_per_cycle = {self.steps_per_cycle} needs synaptic '
                   f'delays of up to {self.steps_per_cycle - 1} steps, but max_delay = '
                   f'{self.max_delay} (Loihi 1 allows at most {LOIHI_MAX_DELAY}); choose '
                   f'steps_per_cycle <= {self.max_delay + 1}')
            raise ConfigError(msg)

    @property
    def dc_wide(self) -> bool:
        """Whether cleanup inputs send their DC neuron on the wider ``dc_payload_bits``."""
        return self.dc_payload_bits > self.payload_bits > 1

    @property
    def widest_payload(self) -> int:
        """The largest graded-spike payload any neuron sends, in bits."""
        cleanup = self.dc_payload_bits if self.dc_wide else self.payload_bits
        return max(cleanup, self.transform_bits if self.transform == 'sparse' else 0)

    @property
    def transform_bits(self) -> int:
        """Payload bits of the sparse transforms' neurons: ``transform_payload_bits``, or
        binary spikes everywhere when ``payload_bits`` is 1 (the Loihi 1 code)."""
        return 1 if self.payload_bits == 1 else self.transform_payload_bits

    @property
    def quantised(self) -> bool:
        """Whether integer state and quantised weights are emulated."""
        return self.precision == 'loihi'
