"""The dataset driver of the odometry pipeline: an Event Camera Dataset through it, frame by frame.

:func:`dataset_pipeline` builds a :class:`~hrn_vo_ros.core.pipeline.OdometryPipeline` for a
dataset folder or zip (the gyro integrator of ``imu.txt`` when asked, the calibration of
``calib.txt`` when the packetizer rectifies); :func:`run_dataset` streams ``events.txt``
through it and returns the estimate series. ``hrn-vo run`` (any resonator backend) and the
accuracy benchmark (the classical baseline) run through these two calls.

ROS 2 bags: :func:`inspect_bag` finds the EventPacket topic (any encoding of
:mod:`hrn_vo_ros.io.eventpacket`), its sensor size and the Imu topics; :func:`bag_pipeline`
and :func:`run_bag` are the bag counterparts of the two calls above.

Clock of bag estimates: the event times inside an EventPacket are sensor times (the driver's
``time_base`` clock for libcaer_cmp, the camera's own counter for evt3), while the messages are
stamped in the host clock of the header. The estimates of :func:`run_bag` carry header-stamp
times. While streaming, a frame's time is its sensor midpoint plus a running offset, the
smallest ``header stamp - first event time`` over the packets so far (the header is stamped at
or after the packet's first event; the smallest difference is the least-delayed packet); the
gyro of the Imu topic (header-stamped too) is integrated up to these times. When the bag is
done, the frame times are mapped once more, piecewise linearly through the anchors
``first event time of packet k -> header stamp of packet k`` (the last anchor being ``last
event time of the last packet -> its header stamp``), which keeps every estimate time inside
the bag's header-stamp span and in increasing order; the two mappings differ by the header
jitter (a few milliseconds).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
import contextlib
from dataclasses import dataclass, field
from pathlib import Path
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.evaluation.series import EstimateSeries
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import EventFrame, Packetizer
from hrn_vo_ros.core.events.packet_config import PacketizerConfig, with_calibration
from hrn_vo_ros.core.events.sequence import (
    calibration_from_camera_info,
    camera_focal,
    CameraCalibration,
    CameraFocal,
)
from hrn_vo_ros.core.hrn.config import needs_focal, ResonatorConfig, sphere_rectify_problem
from hrn_vo_ros.core.live import camera_focal_px
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.core.pipeline import E, OdometryPipeline
from hrn_vo_ros.errors import BagError, ConfigError, DatasetError, DecodeError
from hrn_vo_ros.io import bags, ecd, eventpacket
from hrn_vo_ros.io.ecd.source import read_meta
from hrn_vo_ros.io.yamlconfig import (
    dataset_configs,
    DatasetConfigs,
    load_configs,
    load_sections,
    PACKETIZER_NODE,
)

IMU_TYPE = 'sensor_msgs/msg/Imu'
CAMERA_INFO_TYPE = 'sensor_msgs/msg/CameraInfo'


@dataclass(frozen=True, slots=True, eq=False)
class DatasetRun:
    """What :func:`run_dataset` returns.

    Attributes:
        series: One readout per event frame.
        seconds: Wall time of the streaming loop.
        outside: Events rectified outside the frame (not binned).
        capped: Events left out by the event-rate cap (``max_frame_hz``).
    """

    series: EstimateSeries
    seconds: float
    outside: int
    quality: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    state: list[str] = field(default_factory=list)
    events: int = 0
    stamp_span_ns: tuple[int, int] | None = None
    capped: int = 0


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
    pipeline.finish()               # frames held for the background measurement, if any
    seconds = time.perf_counter() - start
    if not pipeline.frames:
        raise DatasetError(f'fewer events than one packet ({cfg.events_per_frame}); nothing '
                           'to estimate', path=dataset)
    return DatasetRun(pipeline.series(), seconds, packetizer.outside, pipeline.quality(),
                      pipeline.states(), capped=packetizer.capped)


def is_bag(path: Path) -> bool:
    """Whether ``path`` looks like a ROS 2 bag (a folder with ``metadata.yaml``, or a single
    ``.mcap`` / ``.db3`` file) rather than an Event Camera Dataset folder or zip."""
    return ((path.is_dir() and (path / 'metadata.yaml').is_file())
            or (path.is_file() and path.suffix in bags.STORAGE_SUFFIXES))


@dataclass(frozen=True, slots=True)
class BagInfo:
    """What :func:`inspect_bag` found.

    Attributes:
        path: The bag.
        events_topic: The EventPacket topic used.
        encoding: Its encoding (of the first message).
        sensor_size: (width, height) of the first message.
        messages: Message count of the events topic.
        imu_topics: The ``sensor_msgs/msg/Imu`` topics of the bag.
        camera: fx and sensor size of the first usable ``sensor_msgs/msg/CameraInfo`` (the
            topic beside the events topic, else the only one), or None.
        calibration: That CameraInfo's intrinsics and distortion when they are plumb-bob (for
            rectification), or None.
    """

    path: Path
    events_topic: str
    encoding: str
    sensor_size: tuple[int, int]
    messages: int
    imu_topics: tuple[str, ...]
    camera: CameraFocal | None = None
    calibration: CameraCalibration | None = None


def inspect_bag(path: Path, events_topic: str | None = None) -> BagInfo:
    """The event topic (default: the only EventPacket topic), sensor size and camera focal
    length of a bag.

    Raises:
        BagError: for an unreadable bag, no or several EventPacket topics without
            ``events_topic``, an unknown ``events_topic``, or no messages on it.
    """
    ts = bags.typestore()
    with bags.open_bag(path) as reader:
        conns = [c for c in reader.connections if c.msgtype == bags.EVENT_PACKET]
        topics = sorted({c.topic for c in conns})
        imu = tuple(sorted({c.topic for c in reader.connections if c.msgtype == IMU_TYPE}))
        if events_topic is None:
            if len(topics) != 1:
                raise BagError(f'{path}: {len(topics)} EventPacket topics '
                               f'({", ".join(topics) or "none"}); pick one with --events-topic')
            events_topic = topics[0]
        elif events_topic not in topics:
            raise BagError(f'{path}: no EventPacket topic {events_topic}; EventPacket topics: '
                           f'{", ".join(topics) or "none"}')
        count = sum(c.msgcount for c in conns if c.topic == events_topic)
        camera, calibration = _bag_camera(reader, ts, events_topic)
        for m in bags.iter_messages(reader, [events_topic]):
            msg: Any = ts.deserialize_cdr(m.raw, bags.EVENT_PACKET)
            return BagInfo(Path(path), events_topic, str(msg.encoding),
                           (int(msg.width), int(msg.height)), count, imu, camera, calibration)
    raise BagError(f'{path}: {events_topic} has no messages')


def _bag_camera(reader: Any, ts: Any, events_topic: str
                ) -> tuple[CameraFocal | None, CameraCalibration | None]:
    """fx and sensor size of the first usable CameraInfo of the topic beside
    ``events_topic`` (``/event_camera/camera_info`` for ``/event_camera/events``), else of
    the only CameraInfo topic, and its plumb-bob calibration; None for what none gives."""
    topics = sorted({c.topic for c in reader.connections if c.msgtype == CAMERA_INFO_TYPE})
    beside = events_topic.rpartition('/')[0] + '/camera_info'
    topic = beside if beside in topics else topics[0] if len(topics) == 1 else None
    if topic is None:
        return None, None
    for m in bags.iter_messages(reader, [topic]):
        msg: Any = ts.deserialize_cdr(m.raw, CAMERA_INFO_TYPE)
        with contextlib.suppress(DecodeError):
            camera = camera_focal(float(msg.k[0]), int(msg.width), int(msg.height))
            calibration = None
            with contextlib.suppress(DecodeError):
                calibration = calibration_from_camera_info(
                    int(msg.width), int(msg.height), list(msg.k), list(msg.d),
                    str(msg.distortion_model))
            return camera, calibration
    return None, None


def _stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def read_bag_gyro(path: Path, topic: str,
                  camera_from_imu: NDArray[np.float64] | None = None) -> GyroIntegrator:
    """The gyro integrator of an Imu topic (header-stamp times, angular velocity in rad/s).

    Raises:
        BagError: if the topic is not an Imu topic of the bag. DatasetError: for fewer than 2
            samples or times that do not increase.
    """
    ts = bags.typestore()
    t: list[int] = []
    gyro: list[tuple[float, float, float]] = []
    with bags.open_bag(path) as reader:
        if not any(c.topic == topic and c.msgtype == IMU_TYPE for c in reader.connections):
            raise BagError(f'{path}: no {IMU_TYPE} topic {topic}')
        for m in bags.iter_messages(reader, [topic]):
            msg: Any = ts.deserialize_cdr(m.raw, IMU_TYPE)
            w = msg.angular_velocity
            t.append(_stamp_ns(msg))
            gyro.append((float(w.x), float(w.y), float(w.z)))
    if len(t) < 2:
        raise DatasetError(f'{topic}: {len(t)} Imu samples; gyro integration needs 2', path=path)
    out = GyroIntegrator(camera_from_imu)
    out.extend(np.asarray(t, dtype=np.int64), np.asarray(gyro, dtype=np.float64))
    return out


def iter_bag_packets(path: Path, topic: str) -> Iterator[tuple[int, EventArray]]:
    """``(header stamp ns, change events at sensor time)`` of every message of an EventPacket
    topic, decoded in order (stateful encodings keep their state across messages).

    Raises:
        BagError: for a corrupt record. DecodeError: for a corrupt or unknown payload.
    """
    ts = bags.typestore()
    decoder: eventpacket.PacketDecoder | None = None
    with bags.open_bag(path) as reader:
        for k, m in enumerate(bags.iter_messages(reader, [topic])):
            where = f'{path}: {topic}: message {k} (bag time {m.t_ns} ns)'
            try:
                msg: Any = ts.deserialize_cdr(m.raw, bags.EVENT_PACKET)
            except Exception as err:
                raise DecodeError(f'{where}: corrupt EventPacket ({type(err).__name__}: '
                                  f'{err})') from err
            if decoder is None:
                decoder = eventpacket.PacketDecoder(width=int(msg.width) or None,
                                                    height=int(msg.height) or None)
            try:
                ev = decoder.decode(str(msg.encoding), msg.events, time_base=int(msg.time_base),
                                    is_bigendian=bool(msg.is_bigendian))
            except DecodeError as err:
                raise DecodeError(f'{where}: {err}') from err
            yield _stamp_ns(msg), ev


class HeaderClock:
    """Maps sensor event times to header-stamp time (see the module docstring).

    Feed every packet with :meth:`packet`; :meth:`now` maps a time with the running offset,
    :meth:`final` maps times with the anchors of the whole stream.
    """

    def __init__(self) -> None:
        self.offset: int | None = None
        self._first: list[int] = []
        self._stamp: list[int] = []
        self._last_event: int | None = None
        self._last_stamp: int | None = None

    def packet(self, stamp_ns: int, ev: EventArray) -> None:
        """Record one packet's header stamp and events (empty packets only move the span)."""
        self._last_stamp = stamp_ns if self._last_stamp is None else max(self._last_stamp,
                                                                          stamp_ns)
        if len(ev) == 0:
            return
        first = int(ev.t[0])
        off = stamp_ns - first
        self.offset = off if self.offset is None else min(self.offset, off)
        # anchors strictly increasing in both coordinates (a jittered stamp is skipped)
        if not self._first or (first > self._first[-1] and stamp_ns > self._stamp[-1]):
            self._first.append(first)
            self._stamp.append(stamp_ns)
        self._last_event = int(ev.t[-1])

    def now(self, t_ns: int) -> int:
        """``t_ns`` (sensor) plus the running offset."""
        return t_ns + (self.offset or 0)

    def final(self, t_ns: NDArray[np.int64]) -> NDArray[np.int64]:
        """Sensor times mapped through the anchors of all packets, strictly increasing."""
        t = np.asarray(t_ns, dtype=np.int64)
        if not self._first or t.size == 0:
            return np.asarray(t + (self.offset or 0), dtype=np.int64)
        xs = list(self._first)
        ys = list(self._stamp)
        last_stamp = self._last_stamp if self._last_stamp is not None else ys[-1]
        if self._last_event is not None and self._last_event > xs[-1] and last_stamp > ys[-1]:
            xs.append(self._last_event)
            ys.append(last_stamp)
        elif self._last_event is not None and self._last_event > xs[-1] and len(xs) > 1:
            xs[-1] = self._last_event      # the last packet's events end at its stamp
        x = np.asarray(xs, dtype=np.float64)
        y = np.asarray(ys, dtype=np.float64)
        base = y[0]
        out: NDArray[np.int64] = np.round(np.interp(t.astype(np.float64), x, y - base)).astype(
            np.int64)
        out += int(base)
        for i in range(1, out.size):      # ties from clamping or rounding
            if out[i] <= out[i - 1]:
                out[i] = out[i - 1] + 1
        return out

    @property
    def span(self) -> tuple[int, int] | None:
        """First and last header stamp (of packets with events)."""
        if not self._stamp:
            return None
        return self._stamp[0], max(self._stamp[-1], self._last_stamp or self._stamp[-1])


def bag_pipeline(pcfg: PacketizerConfig, make_estimator: Callable[[], E], *,
                 gyro: GyroIntegrator | None = None,
                 with_z: bool = False) -> OdometryPipeline[E]:
    """The pipeline for a bag: a packetizer of ``pcfg`` (rectifying only with a calibration:
    ``calib.*`` or the bag's CameraInfo, :func:`input_configs`), the gyro of its Imu topic
    (:func:`read_bag_gyro`) or None, and the estimator ``make_estimator()``.

    Raises:
        DatasetError: if ``pcfg.rectify`` is not ``none`` and it has no calibration.
    """
    if pcfg.rectify != 'none' and not (pcfg.calib.fx > 0 and pcfg.calib.fy > 0):
        raise DatasetError(f'the packetizer rectifies ({pcfg.rectify}) but the bag has no '
                           'calib.txt nor a plumb-bob CameraInfo: pass --set '
                           'packetizer.rectify=none or the intrinsics (--set '
                           'packetizer.calib.fx=..., fy, cx, cy)')
    return OdometryPipeline(make_estimator(), packetizer=Packetizer(pcfg), gyro=gyro,
                            with_z=with_z)


def run_bag(info: BagInfo, pipeline: OdometryPipeline[E], *,
            on_events: Callable[[int], None] | None = None) -> DatasetRun:
    """Stream the EventPacket topic of a bag through ``pipeline``; estimate times in the
    header-stamp clock (see the module docstring).

    Raises:
        BagError, DecodeError: for a corrupt bag. DatasetError: for events out of order or
            outside the sensor, or fewer events than one packet.
    """
    packetizer = pipeline.packetizer
    if packetizer is None:
        raise DatasetError('the pipeline has no packetizer', path=info.path)
    clock = HeaderClock()
    sensor_t: list[int] = []
    events = 0
    start = time.perf_counter()

    def estimate(frames: list[EventFrame]) -> None:
        for f in frames:
            sensor_t.append(f.t_ns)
            pipeline.step(f.image, clock.now(f.t_ns))

    for stamp, ev in iter_bag_packets(info.path, info.events_topic):
        clock.packet(stamp, ev)
        events += len(ev)
        estimate(packetizer.push(ev))
        if on_events is not None:
            on_events(len(ev))
    estimate(packetizer.finish())   # frames held for the background measurement, if any
    seconds = time.perf_counter() - start
    if not pipeline.frames:
        raise DatasetError(f'{events} events, fewer than one packet '
                           f'({packetizer.cfg.events_per_frame}); nothing to estimate',
                           path=info.path)
    if pipeline.record:
        pipeline.retime(clock.final(np.asarray(sensor_t, dtype=np.int64)))
    return DatasetRun(pipeline.series(), seconds, packetizer.outside, pipeline.quality(),
                      pipeline.states(), events, clock.span, packetizer.capped)



@dataclass(frozen=True, slots=True)
class InputConfigs:
    """What :func:`input_configs` resolves: the stage configs, the warnings and notes to
    print."""

    configs: DatasetConfigs
    warnings: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()


def _file_sensor_size(config: Path | None) -> tuple[int, int] | None:
    """The packetizer ``sensor_width`` / ``sensor_height`` a params file sets, or None."""
    if config is None:
        return None
    pk = load_sections(config).get(PACKETIZER_NODE, {})
    w, h = pk.get('sensor_width'), pk.get('sensor_height')
    return (int(w), int(h)) if isinstance(w, int) and isinstance(h, int) else None


def _read_dataset_first(config: Path | None, source: Path, packetizer: Mapping[str, Any],
                        resonator: Mapping[str, Any]) -> tuple[int, int]:
    """Read a dataset whose sensor size is unknown as a run would (``imu.txt`` when the IMU
    prediction is on, ``calib.txt`` when the packetizer rectifies, all of ``events.txt``), so
    that a broken dataset is reported as such before the missing sensor size; returns the
    extent (max x + 1, max y + 1) of its events.

    Raises:
        DatasetError: for a missing or malformed dataset file, or fewer events than one
            packet.
    """
    pcfg: PacketizerConfig | None
    rcfg: ResonatorConfig | None
    try:     # the settings that decide which files a run reads (the size is a placeholder)
        pcfg, rcfg = load_configs(config, packetizer={**packetizer,
                                                      'sensor_width': ecd.DEFAULT_SENSOR_SIZE[0],
                                                      'sensor_height': ecd.DEFAULT_SENSOR_SIZE[1]},
                                  resonator=resonator)
    except ConfigError:
        pcfg = rcfg = None
    if rcfg is not None and rcfg.imu.enabled:
        ecd.read_imu(source)
    if pcfg is not None and pcfg.rectify != 'none':
        ecd.read_calib(source)
    n, width, height = 0, 0, 0
    for batch in ecd.iter_events(source, sensor_size=(65535, 65535)):
        if len(batch):
            n += len(batch)
            width = max(width, int(batch.x.max()) + 1)
            height = max(height, int(batch.y.max()) + 1)
    if pcfg is not None and n < pcfg.events_per_frame:
        raise DatasetError(f'fewer events than one packet ({pcfg.events_per_frame}); nothing '
                           'to estimate', path=source)
    return width, height


def input_configs(config: Path | None, source: Path, *, bag: BagInfo | None = None,
                  sensor_size: tuple[int, int] | None = None,
                  packetizer: Mapping[str, Any] | None = None,
                  resonator: Mapping[str, Any] | None = None) -> InputConfigs:
    """The stage configs for a dataset folder or zip, or a bag (``bag``).

    Sensor size: ``sensor_size`` (``--sensor-size``) wins, with a warning when it differs from
    what the input says; otherwise a bag's messages (a params-file value that differs is
    reported and not used), a dataset's ``meta.json``, or, for a dataset without one, the
    params file's packetizer ``sensor_width`` / ``sensor_height``; nothing of these is an
    error. For a dataset with ``meta.json`` and no ``sensor_size`` this is
    :func:`~hrn_vo_ros.io.yamlconfig.dataset_configs`.

    Raises:
        ConfigError: when no sensor size is known, for a feature that needs the focal length
            on a bag without ``focal_px``, or as ``dataset_configs``. DatasetError: for a
            malformed dataset file.
    """
    warnings: list[str] = []
    pk = dict(packetizer or {})
    if 'sensor_width' in pk or 'sensor_height' in pk:
        if sensor_size is None and 'sensor_width' in pk and 'sensor_height' in pk:
            sensor_size = (int(pk['sensor_width']), int(pk['sensor_height']))
        pk.pop('sensor_width', None)
        pk.pop('sensor_height', None)
    if bag is None:
        with ecd.SequenceSource(source) as src:
            has_meta = bool(read_meta(src))
        if has_meta and sensor_size is None:
            return InputConfigs(dataset_configs(config, source, packetizer=pk,
                                                resonator=resonator))
        given = ecd.read_sensor_size(source) if has_meta else None
    else:
        given = bag.sensor_size if min(bag.sensor_size) > 0 else None
    what = 'the messages' if bag is not None else 'meta.json'
    if sensor_size is not None:
        if given is not None and given != sensor_size:
            warnings.append(f'--sensor-size {sensor_size[0]}x{sensor_size[1]} overrides the '
                            f'sensor size of {what} ({given[0]}x{given[1]})')
        size = sensor_size
    elif given is not None:
        size = given
        in_file = _file_sensor_size(config)
        if in_file is not None and in_file != given:
            warnings.append(f'{config} sets the sensor size {in_file[0]}x{in_file[1]}; using '
                            f'the size of {what}, {given[0]}x{given[1]} (pass --sensor-size '
                            'to force one)')
    else:
        in_file = _file_sensor_size(config)
        if in_file is None:
            extent = _read_dataset_first(config, source, pk, resonator or {})
            raise ConfigError(f'{source}: no meta.json gives the sensor size (its events span '
                              f'x 0..{extent[0] - 1}, y 0..{extent[1] - 1}); pass '
                              '--sensor-size WxH (e.g. 240x180 for a DAVIS240C) or a --config '
                              'whose packetizer section sets sensor_width and sensor_height')
        size = in_file
    pk.update(sensor_width=size[0], sensor_height=size[1])
    rs = dict(resonator or {})
    pcfg, rcfg = load_configs(config, packetizer=pk, resonator=rs)
    rs.update(width=pcfg.width, height=pcfg.height)
    notes: list[str] = []
    if bag is not None and rcfg.focal_px <= 0.0 and bag.camera is not None:
        rs['focal_px'] = camera_focal_px(bag.camera, (pcfg.width, pcfg.height))   # as the node
        fx, (sw, sh) = bag.camera
        notes.append(f'focal length {rs["focal_px"]:.4g} frame px from the bag\'s CameraInfo '
                     f'(fx {fx:g} on {sw}x{sh}, frames {pcfg.width}x{pcfg.height})')
    elif needs_focal(rcfg):
        if bag is not None:
            raise ConfigError('the IMU prediction and the sphere correction need the focal '
                              'length and the bag has no calib.txt nor a calibrated '
                              'CameraInfo: pass --set focal_px=F (frame pixels) or --set '
                              'sphere.enabled=false')
        rs['focal_px'] = ecd.read_calib(source).fx / pcfg.factor
    pcfg, rcfg = load_configs(config, packetizer=pk, resonator=rs)
    problem = sphere_rectify_problem(pcfg.rectify, rcfg)
    if problem is not None:
        raise ConfigError(problem)
    if bag is not None and bag.calibration is not None and not pcfg.calib.known \
            and pcfg.rectify != 'none':          # as the packetizer node takes a CameraInfo
        pcfg = with_calibration(pcfg, bag.calibration)
        notes.append(f"rectification ({pcfg.rectify}) with the bag's CameraInfo calibration")
    return InputConfigs(DatasetConfigs(pcfg, rcfg, pk, rs), tuple(warnings), tuple(notes))
