"""The HRN's prediction step: the gyro's (with its gate, correction limit and bias) or the
constant-velocity one (``docs/model.md``, sections 6 and 9).

:class:`Prediction` holds the network's methods that move the factor states before a frame's
iterations and judge its readout against the gyro; :class:`~hrn_vo_ros.core.hrn.network.HRN`
inherits them (they act on its engine, pose and counters, which the class declares). The
gyro's mapping to the HRN's coordinates and the bias estimate are in :mod:`.gyro`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.engine import Engine
from hrn_vo_ros.core.hrn.gyro import (
    chart_shift_of_rotation,
    GyroBias,
    rotation_deg,
    rotation_of_shift,
    shift_of_rotation,
)
from hrn_vo_ros.core.hrn.shared import Real
from hrn_vo_ros.errors import ConfigError, TrackingError


class Prediction:
    """The prediction step and the gyro's gate, as methods of the network (a mixin of
    :class:`~hrn_vo_ros.core.hrn.network.HRN`, which sets every attribute below)."""

    cfg: ResonatorConfig
    _engine: Engine
    _point: dict[str, float]                # the last readout (index units, wrapped)
    _prev: dict[str, float] | None          # readout of the last valid frame
    _velocity: dict[str, float] | None      # smoothed readout change per frame
    gyro_bias: GyroBias
    innovation_deg: float
    rejected_frames: int
    limited_frames: int

    def _check_gyro(self, gyro_delta: NDArray[Any]) -> NDArray[np.float64]:
        g = np.asarray(gyro_delta, dtype=np.float64)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise TrackingError(f'gyro_delta must be 3 finite numbers (rad), got {gyro_delta!r}')
        if self.cfg.focal_px <= 0.0:
            raise ConfigError('focal_px must be > 0 for the IMU prediction: set it to the '
                              'focal length in frame pixels (fx / downsample)')
        return g

    def _imu_predict(self, g: NDArray[np.float64]) -> dict[str, float]:
        rb = self._engine.books['r']    # (core/hrn/gyro.py: the content angle's frame)
        alpha = self._point['r'] * rb.unit
        if self.cfg.sphere.enabled:     # the map is the sphere's chart: bind on it exactly
            shift = chart_shift_of_rotation(g, self.cfg.focal_px, self._point['h'],
                                            self._point['v'], alpha, rb.unit)
        else:
            shift = shift_of_rotation(g, self.cfg.focal_px, alpha, rb.unit)
        for name, delta in shift.items():
            self._engine.shift(name, delta)
        return shift

    def _learn_bias(self, point: dict[str, float], predicted: dict[str, float],
                    dt_s: float) -> None:
        """A tracking frame's innovation, as a camera rotation, into the gyro bias."""
        unit = self._engine.books['r'].unit
        self.gyro_bias.update(rotation_of_shift(self._innovation(point, predicted),
                                                self.cfg.focal_px, predicted['r'] * unit, unit),
                              dt_s)

    def _track_velocity(self, point: dict[str, float]) -> None:
        """Update the smoothed h/v/r change per frame (cleanup.predict_smoothing)."""
        prev, self._prev = self._prev, point
        if prev is None:
            return
        a, books = self.cfg.cleanup.predict_smoothing, self._engine.books
        step = {k: books[k].wrap(point[k] - prev[k]) for k in ('h', 'v', 'r')}
        old = self._velocity
        self._velocity = step if old is None else {
            k: (1.0 - a) * old[k] + a * d for k, d in step.items()}

    def _predict_velocity(self) -> dict[str, float]:
        """Constant-velocity prediction: bind h, v, r with a fraction of their velocity;
        returns the shifts (index units)."""
        if self._velocity is None:
            return {}
        k = self.cfg.cleanup.predict_velocity
        for name, d in self._velocity.items():
            self._engine.shift(name, k * d)
        return {name: k * d for name, d in self._velocity.items()}

    def _innovation(self, point: dict[str, float], predicted: dict[str, float]
                    ) -> dict[str, float]:
        """Readout minus gyro prediction (h, v, r; index units, wrapped)."""
        books = self._engine.books
        return {k: books[k].wrap(point[k] - predicted[k]) for k in ('h', 'v', 'r')}

    def _innovation_deg(self, point: dict[str, float], predicted: dict[str, float]) -> float:
        """Largest angle between a readout and the gyro prediction (roll, pan/tilt), degrees."""
        return rotation_deg(self._innovation(point, predicted), self.cfg.focal_px,
                            self._engine.books['r'].unit)

    def _predict(self, first: bool, gyro_delta: NDArray[Any] | None
                 ) -> tuple[dict[str, float] | None, dict[str, Any], dict[str, float]]:
        """Apply the gyro (else the velocity) prediction: (gated prediction, states before it,
        the shift applied)."""
        c, eng = self.cfg, self._engine
        predicted: dict[str, float] | None = None
        held: dict[str, Any] = {}
        shift: dict[str, float] = {}
        if not first and gyro_delta is not None:       # the gyro, else the velocity predicts
            shift = self._imu_predict(gyro_delta)
            predicted = {k: self._point[k] + shift.get(k, 0.0) for k in self._point}
            if c.imu.gate_deg > 0.0 or c.imu.max_correction_deg_s > 0.0:
                held = {k: x.copy() for k, x in eng.state.items()}
        elif c.cleanup.predict_velocity > 0.0:         # no-op until two valid frames
            shift = self._predict_velocity()
        return predicted, held, shift

    def _gate_imu(self, point: dict[str, float], predicted: dict[str, float],
                  held: dict[str, Any], sims: dict[str, Real], dt_s: float,
                  gyro_deg: float
                  ) -> tuple[dict[str, Real], dict[str, float], bool]:
        """The innovation gate and the correction limit, against the gyro's prediction.

        A readout beyond ``imu.gate_deg`` is replaced by the prediction (states restored); one
        within the gate but beyond the limit ``imu.max_correction_deg_s * dt_s +
        imu.max_correction_fraction * gyro_deg`` is cut back to the limit along its own
        direction (the predicted states shifted by the cut difference).
        Returns (sims, point, rejected)."""
        c, eng = self.cfg, self._engine
        books = eng.books
        self.innovation_deg = self._innovation_deg(point, predicted)
        if c.imu.gate_deg > 0.0 and self.innovation_deg > c.imu.gate_deg:
            self.rejected_frames += 1
            eng.state.update(held)
            return eng.similarities(), {k: books[k].wrap(predicted[k]) for k in point}, True
        limit = c.imu.max_correction_deg_s * dt_s + c.imu.max_correction_fraction * gyro_deg
        if c.imu.max_correction_deg_s <= 0.0 or self.innovation_deg <= limit:
            return sims, point, False
        cut = limit / self.innovation_deg
        eng.state.update(held)
        moved = {}
        for k in point:
            d = books[k].wrap(point[k] - predicted[k]) * cut
            eng.shift(k, d)
            moved[k] = books[k].wrap(predicted[k] + d)
        self.limited_frames += 1
        return eng.similarities(), moved, False
