"""The dataset driver of the odometry pipeline: an Event Camera Dataset through it, frame by frame.

:func:`dataset_pipeline` builds a :class:`~hrn_vo_ros.core.pipeline.OdometryPipeline` for a
dataset folder or zip (the gyro integrator of ``imu.txt`` when asked, the calibration of
``calib.txt`` when the packetizer rectifies); :func:`run_dataset` streams ``events.txt``
through it and returns the estimate series. ``hrn-vo run`` (any resonator backend) and the
accuracy benchmark (the classical baseline) run through these two calls.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
import time

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.evaluation.series import EstimateSeries
from hrn_vo_ros.core.events.frames import Packetizer, PacketizerConfig, with_calibration
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.core.pipeline import E, OdometryPipeline
from hrn_vo_ros.errors import DatasetError
from hrn_vo_ros.io import ecd


@dataclass(frozen=True, slots=True, eq=False)
class DatasetRun:
    """What :func:`run_dataset` returns.

    Attributes:
        series: One readout per event frame.
        seconds: Wall time of the streaming loop.
        outside: Events rectified outside the frame (not binned).
    """

    series: EstimateSeries
    seconds: float
    outside: int


def dataset_pipeline(dataset: Path, pcfg: PacketizerConfig, make_estimator: Callable[[], E], *,
                     camera_from_imu: NDArray[np.float64] | None = None,
                     imu: bool = False, with_z: bool = False) -> OdometryPipeline[E]:
    """The pipeline for ``dataset``: its gyro (with ``imu``), its calibration (when
    ``pcfg.rectify`` is not ``none``), a packetizer and the estimator ``make_estimator()``.

    Args:
        dataset: Event Camera Dataset folder or zip.
        pcfg: Packetizer settings (sensor size of the dataset, see ``io.yamlconfig``).
        make_estimator: Builds the estimator (called after the dataset files are read).
        camera_from_imu: Rotation from IMU to camera axes (3x3), default identity.
        imu: Whether to integrate ``imu.txt`` and predict each frame with it.
        with_z: Whether the series carries the log scale.

    Raises:
        DatasetError: for a missing or malformed ``imu.txt`` or ``calib.txt``.
    """
    gyro = GyroIntegrator.from_imu(ecd.read_imu(dataset), camera_from_imu) if imu else None
    if pcfg.rectify != 'none':
        pcfg = with_calibration(pcfg, ecd.read_calib(dataset))
    packetizer = Packetizer(pcfg)
    return OdometryPipeline(make_estimator(), packetizer=packetizer, gyro=gyro, with_z=with_z)


def run_dataset(dataset: Path, pipeline: OdometryPipeline[E], *,
                on_events: Callable[[int], None] | None = None) -> DatasetRun:
    """Stream the events of ``dataset`` through ``pipeline`` (which has a packetizer).

    Args:
        dataset: Event Camera Dataset folder or zip.
        pipeline: From :func:`dataset_pipeline`.
        on_events: Called with the size of every event batch done (a progress bar).

    Raises:
        DatasetError: for malformed events, or fewer events than one packet.
    """
    packetizer = pipeline.packetizer
    if packetizer is None:
        raise DatasetError('the pipeline has no packetizer', path=dataset)
    cfg = packetizer.cfg
    start = time.perf_counter()
    for batch in ecd.iter_events(dataset, sensor_size=(cfg.sensor_width, cfg.sensor_height)):
        pipeline.push(batch)
        if on_events is not None:
            on_events(len(batch))
    seconds = time.perf_counter() - start
    if not pipeline.frames:
        raise DatasetError(f'fewer events than one packet ({cfg.events_per_frame}); nothing '
                           'to estimate', path=dataset)
    return DatasetRun(pipeline.series(), seconds, packetizer.outside)

