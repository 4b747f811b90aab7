"""The hierarchical resonator network: encoding, transforms, engines, the network.

Modules: :mod:`.config` (``ResonatorConfig`` and its sections), :mod:`.fhrr` (FHRR vectors and
FPE codebooks), :mod:`.fft`, :mod:`.logpolar` (Λ and Λ'), :mod:`.sphere` (sphere correction),
:mod:`.shared` (state update, cleanup, factor codebooks, readout), :mod:`.engine` (the
``Engine`` protocol), :mod:`.fast` and :mod:`.dense` (its two float implementations),
:mod:`.network` (``HRN``) and :mod:`.backends` (the backend registry). The model:
``docs/model.md``.
"""
