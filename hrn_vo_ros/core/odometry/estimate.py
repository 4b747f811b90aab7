"""The output of one resonator step (:meth:`hrn_vo_ros.core.hrn.network.HRN.step`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True, slots=True, eq=False)
class Estimate:
    """Pose readout of one event frame, in physical units.

    Attributes:
        t_ns: Frame time (packet midpoint), int64 ns sensor clock.
        h: Camera position in the map, x (right), downsampled pixels, 0 at the first frame.
        v: Camera position in the map, y (down), downsampled pixels, 0 at the first frame.
        r: Roll about the optical axis, radians, right-handed (camera x right, y down, z
            forward), 0 at the first frame, unwrapped over time.
        z: Log scale of the view relative to the map (positive: the camera moved towards the
            scene), 0 when the scale factor is off.
        confidence: Per factor (``h``, ``v``, ``r``, ``z``): peak cosine similarity of the state
            with its codebook, in [-1, 1] (1 = a clean single hypothesis).
        spread: Per factor: standard deviation of the readout around its peak (population
            vector window), in the factor's physical unit; a variance proxy for covariances.
        iteration: Resonator iterations so far (including this frame's).
        map_updated: Whether this step updated the map.
        similarity: Per factor: the normalised readout ``Re(X† x̂)/(|x_j| |x̂|)`` over the
            codebook entries (for readout images), see ``HRN.readout_axis``.
        valid: False when the frame carried no usable input (empty frame) and the previous pose
            was repeated.
        quality: Tracking quality of the frame in [0, 1] (the frame-map overlap at the
            estimate relative to its running reference, see ``docs/model.md``); 1 when not
            computed.
        state: Tracking state: ``tracking``, ``degraded`` (low quality: no map update, no
            velocity prediction) or ``lost`` (the pose is held at the last good one while the
            network re-localises).

    Shapes:
        similarity[name]: (K_name,) float64.
    """

    t_ns: int
    h: float
    v: float
    r: float
    z: float = 0.0
    confidence: dict[str, float] = field(default_factory=dict)
    spread: dict[str, float] = field(default_factory=dict)
    iteration: int = 0
    map_updated: bool = False
    similarity: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    valid: bool = True
    quality: float = 1.0
    state: str = 'tracking'
