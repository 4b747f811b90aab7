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
:class:`~hrn_vo_ros.core.evaluation.protocol.EstimateSeries` (:meth:`OdometryPipeline.series`).
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

    def series(self) -> EstimateSeries:
        """The recorded readouts: ``t`` frame times (ns), ``h``, ``v``, ``r`` [, ``z``]."""
        return EstimateSeries(t=np.array(self._t, dtype=np.int64),
                              h=np.array(self._h, dtype=np.float64),
                              v=np.array(self._v, dtype=np.float64),
                              r=np.array(self._r, dtype=np.float64),
                              z=np.array(self._z, dtype=np.float64) if self.with_z else None)
