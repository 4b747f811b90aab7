"""The odometry pipeline, per frame: events → event frames → estimator → estimate series.

One pipeline serves every way the odometry runs: ``hrn-vo run`` and the accuracy benchmark
(through the dataset driver :mod:`hrn_vo_ros.io.pipeline`, which streams a dataset's events
into :meth:`OdometryPipeline.push`) and the resonator node (frames from the packetizer node
into :meth:`OdometryPipeline.step`, gyro samples into the pipeline's integrator as they
arrive).

Per frame: the gyro prediction since the previous frame
(:meth:`~hrn_vo_ros.core.odometry.imu.GyroIntegrator.increment`, when there is an integrator
and the IMU is used), then ``estimator.step(image, t_ns, gyro_delta=...)``; the estimator is
any object with that step (a resonator backend, float or spiking, or the classical baseline of
:mod:`hrn_vo_ros.core.evaluation.baseline`). With ``record`` the readouts are collected into an
:class:`~hrn_vo_ros.core.evaluation.protocol.EstimateSeries` (:meth:`OdometryPipeline.series`),
with the tracking quality and state of every frame alongside (:meth:`OdometryPipeline.quality`,
:meth:`OdometryPipeline.states`).
"""

from __future__ import annotations

from typing import Any, Generic, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.evaluation.series import EstimateSeries
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import Packetizer
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.errors import ConfigError


class Estimator(Protocol):
    """What the pipeline drives: one pose readout per event frame."""

    def step(self, image: NDArray[Any], t_ns: int, *,
             gyro_delta: NDArray[Any] | None = None) -> Estimate:
        """Process one event frame (H, W); returns the pose readout."""
        ...


E = TypeVar('E', bound=Estimator)


class OdometryPipeline(Generic[E]):
    """Packetizer (optional) + gyro increments (optional) + an estimator, frame by frame.

    Args:
        estimator: The per-frame estimator (replaceable through :attr:`estimator`, e.g. when a
            node reconfigures it).
        packetizer: Makes the event frames for :meth:`push` (not needed for :meth:`step`).
        gyro: The gyro integrator whose increments predict each frame (None: no IMU).
        with_z: Whether :meth:`series` carries the log scale column.
        record: Whether to keep the readouts for :meth:`series` (a node does not).
    """

    def __init__(self, estimator: E, *, packetizer: Packetizer | None = None,
                 gyro: GyroIntegrator | None = None, with_z: bool = False,
                 record: bool = True) -> None:
        self.estimator = estimator
        self.packetizer = packetizer
        self.gyro = gyro
        self.with_z = with_z
        self.record = record
        self._t: list[int] = []
        self._h: list[float] = []
        self._v: list[float] = []
        self._r: list[float] = []
        self._z: list[float] = []
        self._quality: list[float] = []
        self._state: list[str] = []

    @property
    def frames(self) -> int:
        """Frames recorded so far."""
        return len(self._t)

    def step(self, image: NDArray[Any], t_ns: int, *, use_gyro: bool = True) -> Estimate:
        """Estimate the pose of one event frame (with the gyro increment up to ``t_ns`` when
        there is an integrator and ``use_gyro``).

        Raises:
            HrnVoError: whatever the estimator raises (e.g. ``TrackingError``).
        """
        delta = None
        if self.gyro is not None and use_gyro:
            delta = self.gyro.increment(t_ns)
        est = self.estimator.step(image, t_ns, gyro_delta=delta)
        if self.record:
            self._t.append(t_ns)
            self._h.append(est.h)
            self._v.append(est.v)
            self._r.append(est.r)
            self._z.append(est.z)
            self._quality.append(float(getattr(est, 'quality', 1.0)))
            self._state.append(str(getattr(est, 'state', 'tracking')))
        return est

    def push(self, events: EventArray) -> list[Estimate]:
        """Packetize ``events`` (any batch size, in time order) and estimate every frame they
        complete.

        Raises:
            ConfigError: if the pipeline has no packetizer.
            DatasetError: from the packetizer (events outside the sensor or out of order).
        """
        if self.packetizer is None:
            raise ConfigError('this pipeline has no packetizer: feed frames with step()')
        return [self.step(f.image, f.t_ns) for f in self.packetizer.push(events)]

    def finish(self) -> list[Estimate]:
        """End of the stream: estimate the frames the packetizer still held back
        (:meth:`Packetizer.finish`); nothing without a packetizer."""
        if self.packetizer is None:
            return []
        return [self.step(f.image, f.t_ns) for f in self.packetizer.finish()]

    def series(self) -> EstimateSeries:
        """The recorded readouts: ``t`` frame times (ns), ``h``, ``v``, ``r`` [, ``z``]."""
        return EstimateSeries(t=np.array(self._t, dtype=np.int64),
                              h=np.array(self._h, dtype=np.float64),
                              v=np.array(self._v, dtype=np.float64),
                              r=np.array(self._r, dtype=np.float64),
                              z=np.array(self._z, dtype=np.float64) if self.with_z else None)

    def quality(self) -> NDArray[np.float64]:
        """The recorded tracking quality per frame (1 for estimators that do not rate it)."""
        return np.array(self._quality, dtype=np.float64)

    def states(self) -> list[str]:
        """The recorded tracking state per frame (``tracking``, ``degraded`` or ``lost``;
        ``tracking`` for estimators that do not report one)."""
        return list(self._state)

    def retime(self, t_ns: NDArray[np.int64]) -> None:
        """Replace the recorded frame times (one per frame, increasing), e.g. to move them
        to another clock once the whole input is known.

        Raises:
            ConfigError: if the count differs from :attr:`frames` or the times do not increase.
        """
        t = np.asarray(t_ns, dtype=np.int64)
        if t.shape != (len(self._t),) or (t.size > 1 and np.any(np.diff(t) <= 0)):
            raise ConfigError(f'retime: need {len(self._t)} increasing times, got {t.size}')
        self._t = [int(x) for x in t]
