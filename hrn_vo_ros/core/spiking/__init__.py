"""Spiking phasor emulation of the HRN under Loihi constraints (``docs/spiking.md``).

numpy only (Lava cannot be a dependency). Modules: :mod:`.config` (constraints and their
sources), :mod:`.neurons` (phase-to-timing code, resonate-and-fire dynamics), :mod:`.synapses`
(quantised complex synapses), :mod:`.cleanup` (the codebook cleanup as similarity neurons),
:mod:`.accounting` (spikes, synaptic operations, Loihi energy/time estimates).
"""
