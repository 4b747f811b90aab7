"""Datasets to ROS 2 bags: what ``hrn-vo convert`` does, as a pure function.

Sources (:func:`open_source`): an Event Camera Dataset text folder or its ``.zip``, an Event
Camera Dataset ROS 1 ``.bag``, a ROS 2 bag with an EventPacket topic of any known encoding
(e.g. a live ``evt3`` recording) or a dvs_msgs/EventArray topic (events only), a NumPy event
file (``.npy``/``.npz``, see
:mod:`hrn_vo_ros.io.npy`), or a folder holding ``events.npy``/``events.npz`` with the dataset's
side files (``calib.txt``, ``imu.txt``, ``groundtruth.txt`` or a TUM-like ``trajectory.txt``,
optional ``meta.json``). The simulator's output is a text folder, so it converts too.

Output (:func:`convert`): a ROS 2 bag (MCAP by default) with

* ``/event_camera/events``: ``event_camera_msgs/msg/EventPacket``, ``mono`` encoding, packets of
  a fixed duration (grid from the first event) or a fixed event count; ``time_base`` = first
  event's sensor time, ``header.stamp`` = the same, bag time = last event's time (when a driver
  would publish it); best-effort QoS recorded;
* ``/imu``: ``sensor_msgs/msg/Imu`` (orientation unknown: covariance[0] = -1);
* ``/ground_truth/pose``: ``geometry_msgs/msg/PoseStamped`` in frame ``world``;
* ``/event_camera/camera_info``: ``sensor_msgs/msg/CameraInfo`` (``plumb_bob``), once, reliable
  and transient-local (latched).

Every stamp and bag time is the sensor clock (int64 ns). Records are written in bag-time order.
No event is lost or reordered: :class:`ConversionStats` carries the count and an
:class:`~hrn_vo_ros.core.events.arrays.EventChecksum` of what was written, and the bag stores
both in its metadata's ``custom_data`` (keys :data:`~hrn_vo_ros.io.bags.CHECKSUM_KEY`, ...) for
:func:`~hrn_vo_ros.io.bags.verify_bag`. A dataset without ``calib.txt`` converts without
camera_info, with a :class:`~hrn_vo_ros.errors.DatasetWarning` (also in
``ConversionStats.warnings``). The bag is written as
``DST.partial/`` and renamed when complete (:class:`~hrn_vo_ros.io.bags.BagWriter`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass, field
import itertools
from pathlib import Path
import time
from typing import Any
import warnings

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import Qos
from rosbags.typesys.store import Typestore

from hrn_vo_ros.core.events.arrays import EventArray, EventChecksum
from hrn_vo_ros.core.events.sequence import CameraCalibration, ImuData, Trajectory
from hrn_vo_ros.errors import ConfigError, DatasetError, DatasetWarning
from hrn_vo_ros.io import bags, ecd, eventpacket, npy, ros1bag

EVENTS_TOPIC = '/event_camera/events'
IMU_TOPIC = '/imu'
POSE_TOPIC = '/ground_truth/pose'
CAMERA_INFO_TOPIC = '/event_camera/camera_info'
DEFAULT_PACKET_DURATION_MS = 2.0
_SPAN_GRID_NS = 4_000_000_000  # count-based packets never cross this grid (mono spans <= 4.29 s)


# ------------------------------------------------------------------------------------ sources

@dataclass
class Source:
    """An opened dataset: event batches (lazily), side data, sensor size."""

    kind: str
    path: Path
    events: Callable[[], Iterator[EventArray]]
    width: int
    height: int
    calib: CameraCalibration | None = None
    imu: ImuData | None = None
    groundtruth: Trajectory | None = None
    total_events: int | None = None  # exact or estimated, for progress bars
    closer: ExitStack = field(default_factory=ExitStack)
    warnings: list[str] = field(default_factory=list)


def _no_calib_warning(path: Path) -> str:
    """Warn (and return the text) that a dataset without calib.txt gives no camera_info."""
    msg = (f'{path}: no {ecd.CALIB_FILE}: the bag gets no camera_info topic (add calib.txt '
           '"fx fy cx cy k1 k2 p1 p2 k3" to the dataset to have one)')
    warnings.warn(msg, DatasetWarning, stacklevel=3)
    return msg


def open_source(src: Path | str, *, sensor_size: tuple[int, int] | None = None,
                trajectory: Path | str | None = None, time_unit: npy.TimeUnit = 'us',
                ) -> Source:
    """Recognise and open a dataset (see the module docstring for the accepted forms).

    Args:
        src: The dataset path.
        sensor_size: (width, height); needed for NumPy files without ``meta.json``, otherwise it
            overrides the dataset's size (and coordinates are checked against it).
        trajectory: A TUM-like trajectory file used as ground truth (NumPy sources).
        time_unit: Unit of the times in NumPy files.

    Raises:
        DatasetError: for an unknown or incomplete source.
    """
    path = Path(src)
    if path.suffix == '.bag':
        return _open_ros1(path, sensor_size)
    if path.is_dir() and (path / 'metadata.yaml').is_file():
        return _open_ros2(path, sensor_size)
    if path.suffix in ('.npy', '.npz'):
        return _open_npy(path, path.parent, sensor_size, trajectory, time_unit, side=False)
    if path.is_dir():
        for name in ('events.npy', 'events.npz'):
            if (path / name).is_file():
                return _open_npy(path / name, path, sensor_size, trajectory, time_unit,
                                 side=True)
    if path.suffix == '.zip' or (path.is_dir() and (path / ecd.EVENTS_FILE).is_file()):
        return _open_ecd(path, sensor_size)
    if not path.exists():
        raise DatasetError('does not exist', path=path)
    raise DatasetError('is not a dataset: expected an Event Camera Dataset folder (events.txt), '
                       'its .zip, a ROS 1 .bag, or a .npy/.npz event file', path=path)


def _open_ecd(path: Path, sensor_size: tuple[int, int] | None) -> Source:
    size = sensor_size or ecd.read_sensor_size(path)
    calib = ecd.read_calib(path) if _has(path, ecd.CALIB_FILE) else None  # no camera_info then
    if calib is not None and sensor_size is not None:
        calib = _resized(calib, sensor_size)
    seq_imu = ecd.read_imu(path) if _has(path, ecd.IMU_FILE) else None
    seq_gt = ecd.read_groundtruth(path) if _has(path, ecd.GROUNDTRUTH_FILE) else None
    return Source(kind='ecd-zip' if path.suffix == '.zip' else 'ecd-text', path=path,
                  events=lambda: ecd.iter_events(path, sensor_size=size), width=size[0],
                  height=size[1], calib=calib, imu=seq_imu, groundtruth=seq_gt,
                  total_events=ecd.estimate_event_count(path),
                  warnings=[] if calib is not None else [_no_calib_warning(path)])


def _has(path: Path, name: str) -> bool:
    with ecd.SequenceSource(path) as src:
        return src.exists(name)


def _resized(calib: CameraCalibration, size: tuple[int, int]) -> CameraCalibration:
    return CameraCalibration(width=size[0], height=size[1], fx=calib.fx, fy=calib.fy,
                             cx=calib.cx, cy=calib.cy, dist=calib.dist)


def _open_ros1(path: Path, sensor_size: tuple[int, int] | None) -> Source:
    ds = ros1bag.Ros1Dataset(path)
    stack = ExitStack()
    stack.callback(ds.close)
    calib = ds.calib()
    size = sensor_size or (calib and (calib.width, calib.height)) or ds.sensor_size()
    if size is None:
        stack.close()
        raise DatasetError('has no camera_info and no events: cannot tell the sensor size',
                           path=path)
    if calib is not None and sensor_size is not None:
        calib = _resized(calib, sensor_size)
    width, height = size

    def events() -> Iterator[EventArray]:
        for ev in ds.events():
            bad = np.flatnonzero((ev.x >= width) | (ev.y >= height))
            if bad.size:
                i = int(bad[0])
                raise DatasetError(f'event at x={ev.x[i]}, y={ev.y[i]} is outside the '
                                   f'{width}x{height} sensor: give the right sensor size',
                                   path=path)
            yield ev

    return Source(kind='ros1', path=path, events=events, width=width, height=height,
                  calib=calib, imu=ds.imu(), groundtruth=ds.groundtruth(), closer=stack)


def _open_ros2(path: Path, sensor_size: tuple[int, int] | None) -> Source:
    """A ROS 2 bag with an event topic (a live evt3 recording, or dvs_msgs/EventArray as
    ``rosbags-convert`` makes from the dataset's ROS 1 bags): events re-packetised as mono."""
    size = sensor_size
    if size is None:
        ts = bags.typestore()
        with bags.open_bag(path) as reader:
            conns = [c for c in reader.connections
                     if c.msgtype in (bags.EVENT_PACKET, bags.DVS_EVENT_ARRAY)]
            for m in bags.iter_messages(reader, [c.topic for c in conns][:1]):
                if m.msgtype == bags.DVS_EVENT_ARRAY:
                    arr = eventpacket.decode_dvs_cdr(m.raw)
                    size = (arr.width, arr.height)
                else:
                    msg: Any = ts.deserialize_cdr(m.raw, bags.EVENT_PACKET)
                    size = (int(msg.width), int(msg.height))
                break
    if size is None:
        raise DatasetError('has no event messages (EventPacket or dvs EventArray) to take the '
                           'sensor size from; pass --sensor-size', path=path)
    return Source(kind='ros2', path=path, events=lambda: bags.iter_bag_events(path),
                  width=size[0], height=size[1])


def _open_npy(events_file: Path, folder: Path, sensor_size: tuple[int, int] | None,
              trajectory: Path | str | None, time_unit: npy.TimeUnit, *, side: bool) -> Source:
    calib = ecd.read_calib(folder) if side and (folder / ecd.CALIB_FILE).is_file() else None
    size = sensor_size
    if size is None and side and (folder / ecd.META_FILE).is_file():
        size = ecd.read_sensor_size(folder)
    if size is None:
        raise DatasetError('NumPy event files carry no sensor size: pass --sensor-size WxH '
                           '(e.g. 1280x720 for an IMX636)', path=events_file)
    if calib is not None:
        calib = _resized(calib, size)
    imu = ecd.read_imu(folder) if side and (folder / ecd.IMU_FILE).is_file() else None
    gt = None
    if trajectory is not None:
        gt = npy.read_trajectory(trajectory)
    elif side and (folder / ecd.GROUNDTRUTH_FILE).is_file():
        gt = ecd.read_groundtruth(folder)
    elif side and (folder / 'trajectory.txt').is_file():
        gt = npy.read_trajectory(folder / 'trajectory.txt')
    return Source(kind='npy', path=events_file,
                  events=lambda: npy.iter_npy_events(events_file, time_unit=time_unit,
                                                     sensor_size=size),
                  width=size[0], height=size[1], calib=calib, imu=imu, groundtruth=gt,
                  total_events=npy.npy_event_count(events_file),
                  warnings=[_no_calib_warning(folder)] if side and calib is None else [])


# ------------------------------------------------------------------------------------ packets

class PacketSplitter:
    """Cuts a stream of event batches into EventPacket-sized packets, keeping every event.

    Duration mode: packet k holds the events in ``[t0 + k d, t0 + (k + 1) d)`` (``t0`` = first
    event; empty intervals give no packet). Count mode: every ``n`` events, and additionally at
    every 4 s grid line so that a ``mono`` packet never spans more than 2^32 ns.

    Args:
        events_per_packet: ``n`` (count mode), or None.
        duration_ns: ``d`` (duration mode), or None. Exactly one must be given.
    """

    def __init__(self, *, events_per_packet: int | None = None,
                 duration_ns: int | None = None) -> None:
        if (events_per_packet is None) == (duration_ns is None):
            raise ConfigError('give exactly one of events_per_packet and packet duration')
        if events_per_packet is not None and events_per_packet < 1:
            raise ConfigError(f'events_per_packet = {events_per_packet} must be >= 1')
        if duration_ns is not None and not 0 < duration_ns <= eventpacket.MONO_MAX_DT:
            raise ConfigError(f'packet duration {duration_ns / 1e6} ms must be in '
                              f'(0, {eventpacket.MONO_MAX_DT / 1e6:.0f}] ms (mono packets span '
                              'at most 4.29 s)')
        self.n = events_per_packet
        self.d = duration_ns
        self.t0: int | None = None
        self.pending = EventArray.empty()
        self.emitted = 0  # events emitted so far (count-mode phase)

    def push(self, ev: EventArray) -> list[EventArray]:
        """The packets completed by ``ev`` (the last, possibly open one is held back)."""
        buf, bounds = self.push_bounds(ev)
        return [buf[int(a):int(b)] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]

    def push_bounds(self, ev: EventArray) -> tuple[EventArray, NDArray[np.int64]]:
        """Like :meth:`push`, as one array and packet bounds (packet i = ``buf[b[i]:b[i+1]]``).

        Shapes:
            bounds: (k + 1,) for k complete packets (``[0]`` when none).
        """
        if len(ev) == 0:
            return EventArray.empty(), np.zeros(1, np.int64)
        if self.t0 is None:
            self.t0 = int(ev.t[0])
        buf = EventArray.concatenate([self.pending, ev]) if len(self.pending) else ev
        rel = buf.t - np.int64(self.t0)
        n, d = self.n, self.d
        if d is not None:
            bins = rel // np.int64(d)
            cut = np.diff(bins) != 0
        else:
            assert n is not None  # exactly one mode (checked in __init__)
            g = self.emitted + np.arange(1, len(buf), dtype=np.int64)
            grid = rel // np.int64(_SPAN_GRID_NS)
            cut = (g % n == 0) | (np.diff(grid) != 0)
        cuts = np.flatnonzero(cut) + 1
        if n is not None and (self.emitted + len(buf)) % n == 0:
            cuts = np.append(cuts, len(buf))  # a count-mode packet of n events is complete
        bounds = np.concatenate(([0], cuts)).astype(np.int64)
        end = int(bounds[-1])
        self.pending = buf[end:]
        self.emitted += end
        return buf[:end], bounds

    def flush(self) -> list[EventArray]:
        """The last, open packet (if any)."""
        out = [self.pending] if len(self.pending) else []
        self.emitted += len(self.pending)
        self.pending = EventArray.empty()
        return out


# ------------------------------------------------------------------------------------ convert

@dataclass(frozen=True, slots=True)
class ConversionStats:
    """What :func:`convert` wrote."""

    events: int
    packets: int
    imu: int
    poses: int
    camera_info: int
    checksum: str
    first_t_ns: int | None
    last_t_ns: int | None
    seconds: float
    source_kind: str
    warnings: tuple[str, ...] = ()

    @property
    def events_per_second(self) -> float:
        """Conversion throughput (events per wall-clock second)."""
        return self.events / max(self.seconds, 1e-9)


def convert(src: Path | str, dst: Path | str, *, storage: bags.Storage = 'mcap',
            events_per_packet: int | None = None, packet_duration_ms: float | None = None,
            frame_id: str = 'event_camera', sensor_size: tuple[int, int] | None = None,
            trajectory: Path | str | None = None, time_unit: npy.TimeUnit = 'us',
            progress: Callable[[int], None] | None = None,
            on_source: Callable[[Source], None] | None = None) -> ConversionStats:
    """Convert a dataset to a ROS 2 bag (see the module docstring for topics and stamps).

    Args:
        src: The dataset (see :func:`open_source`).
        dst: The bag directory to create; must not exist.
        storage: ``'mcap'`` or ``'sqlite3'``.
        events_per_packet: Fixed-count packets; or
        packet_duration_ms: fixed-duration packets (default 2 ms when neither is given).
        frame_id: ``header.frame_id`` of events and camera info.
        sensor_size: (width, height) override / for NumPy files.
        trajectory: Ground-truth trajectory file for NumPy sources.
        time_unit: Time unit of NumPy files.
        progress: Called with the number of events of each converted batch.
        on_source: Called once with the opened source (e.g. to size a progress bar).

    Raises:
        DatasetError: bad input (nothing is left at ``dst``).
        BagError: ``dst`` exists.
        ConfigError: invalid packet options.
    """
    start = time.perf_counter()
    splitter = _packet_splitter(events_per_packet, packet_duration_ms)
    dst = Path(dst)
    bags._check_target(dst)
    source = open_source(src, sensor_size=sensor_size, trajectory=trajectory,
                         time_unit=time_unit)
    try:
        if on_source is not None:
            on_source(source)
        writer_cm = bags.BagWriter(dst, storage=storage)
    except BaseException:
        source.closer.close()
        raise
    with source.closer, writer_cm as writer:
        written = _write_bag(source, writer, splitter, frame_id, progress)
        counts = dict(writer.counts)
        writer.set_custom_data(bags.CHECKSUM_KEY, written.checksum.hexdigest())
        writer.set_custom_data(bags.COUNT_KEY, str(written.checksum.count))
        writer.set_custom_data(bags.TOPIC_KEY, EVENTS_TOPIC)
    return ConversionStats(events=written.checksum.count, packets=written.packets,
                           imu=counts.get(IMU_TOPIC, 0), poses=counts.get(POSE_TOPIC, 0),
                           camera_info=counts.get(CAMERA_INFO_TOPIC, 0),
                           checksum=written.checksum.hexdigest(), first_t_ns=written.first_t,
                           last_t_ns=written.last_t, seconds=time.perf_counter() - start,
                           source_kind=source.kind, warnings=tuple(source.warnings))


def _packet_splitter(events_per_packet: int | None,
                     packet_duration_ms: float | None) -> PacketSplitter:
    """The splitter for the packet options (2 ms packets when neither is given)."""
    if events_per_packet is None and packet_duration_ms is None:
        packet_duration_ms = DEFAULT_PACKET_DURATION_MS
    if events_per_packet is not None and packet_duration_ms is not None:
        raise ConfigError('give either --events-per-packet or --packet-duration, not both')
    duration_ns = None if packet_duration_ms is None else round(packet_duration_ms * 1e6)
    return PacketSplitter(events_per_packet=events_per_packet, duration_ns=duration_ns)


class _EventBag:
    """The records of one conversion: mono EventPackets, and the side records (IMU, poses,
    camera info) written before the first packet published after them (bag-time order).

    Args:
        writer: The open bag.
        source: The dataset (topics, side data, sensor size).
        frame_id: ``header.frame_id`` of events and camera info.
        t_start: Sensor time of the first event (None: no events).
    """

    def __init__(self, writer: bags.BagWriter, source: Source, frame_id: str,
                 t_start: int | None) -> None:
        self.writer = writer
        self.source = source
        self.frame_id = frame_id
        self.side = _side_messages(source, writer.ts, frame_id, t_start)
        self.conns = {topic: writer.add_topic(topic, msgtype, qos)
                      for topic, msgtype, qos in _topics(source)}
        self.k = 0        # side records written so far
        self.packets = 0  # event packets written so far

    def flush_side(self, until: int | None) -> None:
        """Write the side records stamped at or before ``until`` (None: all the rest)."""
        while self.k < len(self.side) and (until is None or self.side[self.k][0] <= until):
            t, topic, raw = self.side[self.k]
            self.writer.write(self.conns[topic], t, raw)
            self.k += 1

    def write_packets(self, buf: EventArray, bounds: NDArray[np.int64]) -> None:
        """Write packets ``buf[bounds[i]:bounds[i + 1]]``, each at its last event's time."""
        if len(bounds) < 2:
            return
        time_bases, payload = eventpacket.encode_mono_packets(buf, bounds)
        ends = buf.t[bounds[1:] - 1].tolist()
        for i, (a, b) in enumerate(zip((8 * bounds[:-1]).tolist(),
                                       (8 * bounds[1:]).tolist(), strict=True)):
            time_base, t_pub = int(time_bases[i]), ends[i]
            self.flush_side(t_pub)
            raw = bags.event_packet_cdr(
                stamp_ns=time_base, frame_id=self.frame_id, height=self.source.height,
                width=self.source.width, seq=self.packets, time_base=time_base,
                encoding='mono', is_bigendian=False, payload=payload[a:b])
            self.writer.write(self.conns[EVENTS_TOPIC], t_pub, raw)
            self.packets += 1


@dataclass(frozen=True, slots=True)
class _Written:
    """The events :func:`_write_bag` wrote."""

    checksum: EventChecksum
    packets: int
    first_t: int | None
    last_t: int | None


def _write_bag(source: Source, writer: bags.BagWriter, splitter: PacketSplitter, frame_id: str,
               progress: Callable[[int], None] | None) -> _Written:
    """Stream the source's events into packets and write everything to the open bag."""
    checksum = EventChecksum()
    first_t: int | None = None
    last_t: int | None = None
    batches = source.events()
    first = next((ev for ev in batches if len(ev)), EventArray.empty())
    bag = _EventBag(writer, source, frame_id, int(first.t[0]) if len(first) else None)
    for ev in itertools.chain([first], batches):
        if len(ev) == 0:
            continue
        checksum.update(ev)
        if first_t is None:
            first_t = int(ev.t[0])
        last_t = int(ev.t[-1])
        bag.write_packets(*splitter.push_bounds(ev))
        if progress is not None:
            progress(len(ev))
    for last in splitter.flush():
        bag.write_packets(last, np.array([0, len(last)], np.int64))
    bag.flush_side(None)
    return _Written(checksum, bag.packets, first_t, last_t)


def _topics(source: Source) -> list[tuple[str, str, Qos]]:
    topics = [(EVENTS_TOPIC, bags.EVENT_PACKET, bags.EVENTS_QOS)]
    if source.imu is not None:
        topics.append((IMU_TOPIC, 'sensor_msgs/msg/Imu', bags.SENSOR_QOS))
    if source.groundtruth is not None:
        topics.append((POSE_TOPIC, 'geometry_msgs/msg/PoseStamped', bags.RELIABLE_QOS))
    if source.calib is not None:
        topics.append((CAMERA_INFO_TOPIC, 'sensor_msgs/msg/CameraInfo',
                       bags.make_qos(reliable=True, depth=1, transient_local=True)))
    return topics


def _side_messages(source: Source, ts: Typestore, frame_id: str, t_start: int | None,
                   ) -> list[tuple[int, str, bytes]]:
    """IMU, pose and camera-info records (bag time, topic, CDR), sorted by time."""
    T = ts.types

    def header(t: int, frame: str) -> Any:
        return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=t // 1_000_000_000, nanosec=t % 1_000_000_000), frame_id=frame)

    out: list[tuple[int, str, bytes]] = []
    if source.imu is not None:
        imu = source.imu
        raws = bags.imu_cdr_batch(imu.t, imu.acc, imu.gyro, frame_id='imu')
        out += [(t, IMU_TOPIC, raw) for t, raw in zip(imu.t.tolist(), raws, strict=True)]
    if source.groundtruth is not None:
        gt = source.groundtruth
        raws = bags.pose_cdr_batch(gt.t, gt.pos, gt.quat, frame_id='world')
        out += [(t, POSE_TOPIC, raw) for t, raw in zip(gt.t.tolist(), raws, strict=True)]
    if source.calib is not None:
        c = source.calib
        starts = [t for t, _, _ in out[:1]] + ([] if t_start is None else [t_start])
        if source.groundtruth is not None and len(source.groundtruth):
            starts.append(int(source.groundtruth.t[0]))
        t0 = min(starts, default=0)  # first record of the bag: latched before everything
        m = T['sensor_msgs/msg/CameraInfo'](
            header=header(t0, frame_id), height=c.height, width=c.width,
            distortion_model='plumb_bob', d=np.array(c.dist, np.float64),
            k=np.array([c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1], np.float64),
            r=np.eye(3).ravel(),
            p=np.array([c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0], np.float64),
            binning_x=0, binning_y=0,
            roi=T['sensor_msgs/msg/RegionOfInterest'](x_offset=0, y_offset=0, height=0,
                                                      width=0, do_rectify=False))
        out.append((t0, CAMERA_INFO_TOPIC, bytes(ts.serialize_cdr(
            m, 'sensor_msgs/msg/CameraInfo'))))
    out.sort(key=lambda r: r[0])
    return out
