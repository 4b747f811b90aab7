"""What the network needs from an engine: the public :class:`Engine` protocol.

An engine holds the factor states and the map and computes the resonator equations on them
(``docs/model.md``); :class:`~hrn_vo_ros.core.hrn.network.HRN` does the rest (frame checks,
sphere correction, kernel blur, predictions, readout, the innovation gate, the map schedule).
Implementations: :class:`~hrn_vo_ros.core.hrn.fast.FastEngine` (FFTs, factorised states),
:class:`~hrn_vo_ros.core.hrn.dense.DenseEngine` (the dense reference) and the spiking backend's
:class:`~hrn_vo_ros.core.spiking.backend.SpikingEngine`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.logpolar import Geometry
from hrn_vo_ros.core.hrn.shared import FactorCodebook, Floats, Real


class Engine(Protocol):
    """The resonator equations on one representation of the states and the map.

    ``S`` is the engine's encoding of a frame (whatever :meth:`encode` returns); ``point`` maps
    each factor name to its readout exponent (index units, wrapped, as
    :meth:`FactorCodebook.wrap`). An engine may also offer ``relocalise(S, rolls, z, keep)``
    (the global search of the re-localisation, :meth:`.fast.FastEngine.relocalise`); without
    it, a lost track holds its pose until the states find the map again by themselves.

    Attributes:
        books: The factor codebooks by name (``h``, ``v``, ``r`` [, ``z``]), in factor order.
        state: The factor states by name; the network copies and restores them (IMU gate).
        drive: ``Re X† u`` of each factor's last cleanup input over its bound ``|x_j| |a|``
            (``a``: the factor's marginal of ``u``, the 1-D input it cleans, in either engine);
            may be empty when the configuration does not read it (``readout.source = drive``).
    """

    books: dict[str, FactorCodebook]
    state: dict[str, Any]
    drive: dict[str, Real]

    @property
    def blur_dtype(self) -> type[np.floating]:
        """The float type the network blurs the placed canvas in (``codebook.kernel_sigma``):
        float32 where the engine rounds its input to single precision anyway."""
        ...

    def encode(self, canvas: Floats) -> Any:
        """The frame ``S`` as the iteration consumes it. Shapes: canvas (H_c, W_c)."""
        ...

    def start(self, canvas: Floats, rng: np.random.Generator) -> None:
        """Initial states (``cleanup.init``) and the first map ``m̂(0) = s(0)``."""
        ...

    def iterate(self, S: Any) -> None:
        """One synchronous resonator iteration of every factor state on frame ``S``."""
        ...

    def similarities(self) -> dict[str, Real]:
        """Normalised ``Re X† x`` of every factor state (the readout similarities)."""
        ...

    def shift(self, name: str, delta: float) -> None:
        """Bind factor ``name``'s state with ``seed^delta`` (a prediction, index units)."""
        ...

    def set_point(self, point: dict[str, float]) -> None:
        """Set every factor state to its codebook vector at ``point`` (a restart)."""
        ...

    def map_target(self, S: Any, point: dict[str, float]) -> Any:
        """The frame ``S`` moved into the map at ``point`` (the update's target ``m(t)``)."""
        ...

    def overlap(self, target: Any) -> float:
        """Normalised overlap of the map with a :meth:`map_target`, in [-1, 1]."""
        ...

    def distinctiveness(self, target: Any) -> float:
        """How much better the map matches a :meth:`map_target` at the estimate than at other
        shifts (a peak-to-sidelobe ratio); NaN where the engine does not compute it."""
        ...

    def update_map(self, S: Any, point: dict[str, float], mu1: float, mu2: float,
                   target: Any = None) -> None:
        """The anchored map update ``m̂ ← μ1 m̂ + μ2 m̂(0) + (1-μ1-μ2) m(t)`` at ``point``
        (``target``: ``m(t)`` if the caller already has it from :meth:`map_target`)."""
        ...

    def map_image(self, point: dict[str, float] | None) -> Real:
        """The map as a canvas image: allocentric (None) or moved into the view at ``point``."""
        ...

    def input_projection(self, name: str) -> Any:
        """``phasor(X X† u)`` of factor ``name``'s last cleanup input u (readout.refine_input)."""
        ...


#: Builds the engine for a configuration and its geometry (``HRN(engine=...)``).
EngineFactory = Callable[[ResonatorConfig, Geometry], Engine]
