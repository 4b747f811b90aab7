"""Resonator backends: one interface, a float reference and a spiking emulation.

``ResonatorBackend`` is the interface the CLIs and nodes use (the public API of
:class:`~hrn_vo_ros.core.hrn.network.HRN`). Implementations, selected by name (:data:`BACKENDS`):

* ``'float'``: :class:`~hrn_vo_ros.core.hrn.network.HRN`, the float reference (fast or dense path);
* ``'spiking'``: :class:`~hrn_vo_ros.core.spiking.backend.SpikingHRN`, the same network as
  spiking phasor neurons under Loihi constraints (:class:`SpikingConfig`).

Backends that report spikes also satisfy :class:`SpikingDiagnostics` (spike raster and
per-iteration accounting).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.configbase import nested, param, validate
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.gyro import GyroBias
from hrn_vo_ros.core.hrn.logpolar import Geometry
from hrn_vo_ros.core.hrn.network import HRN
from hrn_vo_ros.core.hrn.tracking import Tracker
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.spiking.backend import SpikingHRN
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.errors import ConfigError


@runtime_checkable
class ResonatorBackend(Protocol):
    """What a resonator backend offers (see `HRN` for semantics)."""

    cfg: ResonatorConfig
    geometry: Geometry
    factors: tuple[str, ...]
    iteration: int
    rejected_frames: int      # frames rejected by the IMU innovation gate (imu.gate_deg)
    limited_frames: int       # readouts cut by the IMU correction limit (imu.max_correction_*)
    tracker: Tracker          # quality, state and their counts (tracker.distinct: smoothed
    #                           distinctiveness, NaN when not computed)
    gyro_bias: GyroBias       # the online gyro bias estimate (imu.bias_memory_s)

    @property
    def hot_pixels(self) -> int:
        """On pixels of the last frame masked as hot (hot_pixel_*)."""
        ...

    def step(self, image: NDArray[Any], t_ns: int, *,
             gyro_delta: NDArray[Any] | None = None) -> Estimate:
        """Process one event frame (H, W); returns the pose readout."""
        ...

    def reset(self) -> None:
        """Forget the map and the states."""
        ...

    def map_image(self) -> NDArray[np.float64]:
        """The allocentric map as an image (canvas)."""
        ...

    def egocentric_map_image(self) -> NDArray[np.float64]:
        """The map moved into the current view."""
        ...

    def readout_axis(self, name: str) -> NDArray[np.float64]:
        """Physical value of each readout entry of factor ``name``."""
        ...


@runtime_checkable
class SpikingDiagnostics(Protocol):
    """Extra outputs of a spiking backend."""

    def raster(self) -> NDArray[np.uint8]:
        """Spike raster of the last cycle (neurons x time steps)."""
        ...

    def account_summary(self) -> dict[str, float]:
        """Per-iteration spikes, synaptic operations, neuron updates and Loihi estimates."""
        ...


def _float(cfg: ResonatorConfig, rng: np.random.Generator,
           spiking: SpikingConfig) -> ResonatorBackend:
    return HRN(cfg, rng=rng)


def _spiking(cfg: ResonatorConfig, rng: np.random.Generator,
             spiking: SpikingConfig) -> ResonatorBackend:
    return SpikingHRN(cfg, rng=rng, spiking=spiking)


#: Backend name -> class (the registry; ``make_backend`` builds one from a config).
BACKENDS: dict[str, type[Any]] = {'float': HRN, 'spiking': SpikingHRN}
_FACTORIES = {'float': _float, 'spiking': _spiking}


@dataclass(frozen=True, slots=True)
class BackendConfig:
    """Which resonator backend runs, and the spiking emulation's settings."""

    name: str = param('float', 'resonator backend: float (reference) or spiking (phasor '
                      'neurons under Loihi constraints)', choices=tuple(BACKENDS),
                      read_only=True)
    spiking: SpikingConfig = nested(SpikingConfig, 'spiking emulation (backend spiking)')

    def __post_init__(self) -> None:
        validate(self)


def make_backend(cfg: ResonatorConfig, *, rng: np.random.Generator,
                 backend: BackendConfig | str = 'float') -> ResonatorBackend:
    """Build the backend named by ``backend`` for resonator config ``cfg``.

    Raises:
        ConfigError: for an unknown backend name (listing the known ones).
    """
    bc = BackendConfig(name=backend) if isinstance(backend, str) else backend
    try:
        factory = _FACTORIES[bc.name]
    except KeyError:
        raise ConfigError(f'unknown backend {bc.name!r}; choose one of '
                          f'{", ".join(BACKENDS)}') from None
    return factory(cfg, rng, bc.spiking)
