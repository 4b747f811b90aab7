"""Spiking phasor emulation of the HRN under Loihi constraints (``docs/spiking.md``).

numpy/scipy only (Lava cannot be a dependency). Modules: :mod:`.config` (constraints and their
sources), :mod:`.neurons` (phase-to-timing code, resonate-and-fire dynamics), :mod:`.synapses`
(quantised complex synapses), :mod:`.cleanup` (the codebook cleanup as similarity neurons),
:mod:`.accounting` (spikes, synaptic operations, Loihi energy/time estimates), :mod:`.backend`
(the spiking HRN, dense transform form), :mod:`.butterfly` and :mod:`.transforms` (Λ, Λ' as
butterfly and log-polar tap layers), :mod:`.sparse_engine` (the sparse form, default),
:mod:`.hardware` and :mod:`.resources` (chip limits, cores and chips), :mod:`.report` (the
resource report of ``hrn-vo spiking-report``).
"""
