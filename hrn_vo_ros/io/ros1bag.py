"""Event Camera Dataset ROS 1 bags (``rosbags.rosbag1``): read fast, and write fixtures.

Topics of the dataset's bags (as the dataset publishes them): ``/dvs/events``
(``dvs_msgs/EventArray``, decoded with numpy from the packed 13-byte records, no per-event
objects), ``/dvs/imu`` (``sensor_msgs/Imu``), ``/optitrack/davis`` (``geometry_msgs/PoseStamped``,
absent in outdoor sequences) and ``/dvs/camera_info`` (``sensor_msgs/CameraInfo``). Times are the
message stamps (event ``ts``, header stamps) in int64 ns.

Public API: :class:`Ros1Dataset` (``events()`` iterator, ``imu()``, ``groundtruth()``,
``calib()``, ``n_event_messages``) and :func:`write_ros1_bag` (a
:class:`~hrn_vo_ros.core.events.sequence.Sequence` as such a bag, for fixtures and tests).
"""

from __future__ import annotations

from collections.abc import Iterator
import functools
from pathlib import Path
import struct
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import Connection
from rosbags.rosbag1 import Reader, Writer
from rosbags.typesys import get_types_from_msg, Stores
from rosbags.typesys import get_typestore as _get_typestore
from rosbags.typesys.store import Typestore

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import CameraCalibration, ImuData, Sequence, Trajectory
from hrn_vo_ros.errors import BagError, DatasetError, DecodeError
from hrn_vo_ros.io import eventpacket

EVENTS_TOPIC = '/dvs/events'
IMU_TOPIC = '/dvs/imu'
POSE_TOPIC = '/optitrack/davis'
CAMERA_INFO_TOPIC = '/dvs/camera_info'
DVS_TYPE = 'dvs_msgs/msg/EventArray'

_DVS_ROS1_MSGS = {
    'dvs_msgs/msg/Event': 'uint16 x\nuint16 y\ntime ts\nbool polarity\n',
    'dvs_msgs/msg/EventArray': 'Header header\nuint32 height\nuint32 width\nEvent[] events\n',
}


@functools.cache
def ros1_typestore() -> Typestore:
    """ROS 1 Noetic types plus the ROS 1 ``dvs_msgs`` definitions."""
    ts = _get_typestore(Stores.ROS1_NOETIC)
    types = {}
    for name, text in _DVS_ROS1_MSGS.items():
        types.update(get_types_from_msg(text, name))
    ts.register(types)
    return ts


def _stamp_ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class Ros1Dataset:
    """A ROS 1 bag of the Event Camera Dataset, opened for reading (use as a context manager).

    Args:
        path: The ``.bag`` file.
        events_topic, imu_topic, pose_topic, camera_info_topic: Topic names (dataset defaults).

    Raises:
        BagError: if the bag is missing, corrupt, or has no event topic.
    """

    def __init__(self, path: Path | str, *, events_topic: str = EVENTS_TOPIC,
                 imu_topic: str = IMU_TOPIC, pose_topic: str = POSE_TOPIC,
                 camera_info_topic: str = CAMERA_INFO_TOPIC) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise BagError(f'{self.path} does not exist or is not a file: give a ROS 1 .bag')
        try:
            self.reader = Reader(self.path)
            self.reader.open()
        except Exception as err:
            raise BagError(f'{self.path}: cannot read the ROS 1 bag ({type(err).__name__}: '
                           f'{err})') from err
        self.ts = ros1_typestore()
        self.topics = {c.topic: c for c in self.reader.connections}
        self.events_topic = events_topic
        self.imu_topic, self.pose_topic = imu_topic, pose_topic
        self.camera_info_topic = camera_info_topic
        conns = self._conns(events_topic)
        if not conns:
            found = ', '.join(sorted(self.topics)) or 'none'
            raise BagError(f'{self.path}: no {events_topic} topic (topics: {found})')
        if conns[0].msgtype != DVS_TYPE:
            raise BagError(f'{self.path}: {events_topic} is {conns[0].msgtype}, expected '
                           f'{DVS_TYPE}')
        self.n_event_messages = sum(c.msgcount for c in conns)

    def _conns(self, topic: str) -> list[Connection]:
        return [c for c in self.reader.connections if c.topic == topic]

    def _raw(self, topic: str) -> Iterator[tuple[int, bytes]]:
        conns = self._conns(topic)
        if not conns:
            return
        it = self.reader.messages(connections=conns)
        while True:
            try:
                _conn, t, raw = next(it)
            except StopIteration:
                return
            except Exception as err:
                raise BagError(f'{self.path}: corrupt record on {topic} '
                               f'({type(err).__name__}: {err})') from err
            yield t, raw

    def _msgs(self, topic: str, msgtype: str) -> Iterator[Any]:
        """Deserialised messages of ``topic``; a corrupt one raises DecodeError naming it."""
        for i, (t, raw) in enumerate(self._raw(topic)):
            try:
                yield self.ts.deserialize_ros1(raw, msgtype)
            except Exception as err:  # rosbags raises its own and struct/index errors
                raise DecodeError(f'{self.path}: {topic} message {i} (bag time {t} ns): '
                                  f'corrupt {msgtype} ({type(err).__name__}: {err})') from err

    def _finite(self, topic: str, values: NDArray[np.float64]) -> NDArray[np.float64]:
        bad = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
        if bad.size:
            raise DatasetError(f'{topic} message {int(bad[0])} holds a non-finite value '
                               f'{values[int(bad[0])].tolist()}: a corrupt message',
                               path=self.path)
        return values

    def events(self) -> Iterator[EventArray]:
        """Events of every ``/dvs/events`` message, in bag order (one batch per message).

        Raises:
            DatasetError: if event times go backwards.
            DecodeError: on a truncated message.
        """
        last = -(1 << 62)
        for i, (_t, raw) in enumerate(self._raw(self.events_topic)):
            try:
                ev = eventpacket.decode_dvs_ros1(raw).events
            except DecodeError as err:
                raise DecodeError(f'{self.path}: {self.events_topic} message {i}: {err}'
                                  ) from err
            if len(ev) == 0:
                continue
            if ev.t[0] < last or np.any(ev.t[1:] < ev.t[:-1]):
                raise DatasetError(f'{self.events_topic} message {i}: event times go '
                                   'backwards: events must be sorted by time', path=self.path)
            last = int(ev.t[-1])
            yield ev

    def imu(self) -> ImuData | None:
        """All ``/dvs/imu`` samples (header stamps), or None if the topic is absent."""
        t, acc, gyro = [], [], []
        for m in self._msgs(self.imu_topic, 'sensor_msgs/msg/Imu'):
            t.append(_stamp_ns(m.header.stamp))
            a, g = m.linear_acceleration, m.angular_velocity
            acc.append((a.x, a.y, a.z))
            gyro.append((g.x, g.y, g.z))
        if not t:
            return None
        return ImuData(t=np.array(t, np.int64),
                       acc=self._finite(self.imu_topic, np.array(acc, np.float64)),
                       gyro=self._finite(self.imu_topic, np.array(gyro, np.float64)))

    def groundtruth(self) -> Trajectory | None:
        """All ``/optitrack/davis`` poses (header stamps), or None if the topic is absent."""
        t, pos, quat = [], [], []
        for m in self._msgs(self.pose_topic, 'geometry_msgs/msg/PoseStamped'):
            t.append(_stamp_ns(m.header.stamp))
            p, q = m.pose.position, m.pose.orientation
            pos.append((p.x, p.y, p.z))
            quat.append((q.x, q.y, q.z, q.w))
        if not t:
            return None
        return Trajectory(t=np.array(t, np.int64),
                          pos=self._finite(self.pose_topic, np.array(pos, np.float64)),
                          quat=self._finite(self.pose_topic, np.array(quat, np.float64)))

    def calib(self) -> CameraCalibration | None:
        """Calibration from the first ``/dvs/camera_info``, or None if the topic is absent."""
        for m in self._msgs(self.camera_info_topic, 'sensor_msgs/msg/CameraInfo'):
            k = [float(v) for v in m.K]
            d = [float(v) for v in m.D][:5]
            d += [0.0] * (5 - len(d))
            return CameraCalibration(width=int(m.width), height=int(m.height), fx=k[0], fy=k[4],
                                     cx=k[2], cy=k[5], dist=(d[0], d[1], d[2], d[3], d[4]))
        return None

    def sensor_size(self) -> tuple[int, int] | None:
        """(width, height) from the first event message (or None if it has none)."""
        for i, (_t, raw) in enumerate(self._raw(self.events_topic)):
            try:
                arr = eventpacket.decode_dvs_ros1(raw)
            except DecodeError as err:
                raise DecodeError(f'{self.path}: {self.events_topic} message {i}: {err}'
                                  ) from err
            return arr.width, arr.height
        return None

    def close(self) -> None:
        self.reader.close()

    def __enter__(self) -> Ros1Dataset:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def encode_dvs_ros1(ev: EventArray, *, stamp_ns: int, seq: int, frame_id: str, width: int,
                    height: int) -> bytes:
    """ROS 1 serialised ``dvs_msgs/EventArray`` (packed 13-byte events), built with numpy."""
    fid = frame_id.encode()
    head = struct.pack('<III', seq, stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)
    head += struct.pack('<I', len(fid)) + fid + struct.pack('<III', height, width, len(ev))
    rec = np.empty(len(ev), np.dtype([('x', '<u2'), ('y', '<u2'), ('sec', '<u4'),
                                      ('nsec', '<u4'), ('p', 'u1')]))
    rec['x'], rec['y'], rec['p'] = ev.x, ev.y, ev.p
    rec['sec'], rec['nsec'] = np.divmod(ev.t, 1_000_000_000)
    return head + rec.tobytes()


def write_ros1_bag(path: Path | str, seq: Sequence, *, events_per_message: int = 5000,
                   t_offset_ns: int = 0) -> Path:
    """Write ``seq`` as an Event Camera Dataset style ROS 1 bag (fixtures and tests).

    Args:
        path: The ``.bag`` file to create (must not exist).
        seq: The sequence; times are shifted by ``t_offset_ns`` (the dataset's bags use epoch
            stamps), so the times must stay >= 0.
        events_per_message: Events per ``/dvs/events`` message.
        t_offset_ns: Added to every stamp.

    Raises:
        BagError: if ``path`` exists.
    """
    path = Path(path)
    if path.exists():
        raise BagError(f'{path} exists already: not overwriting')
    ts = ros1_typestore()
    T = ts.types
    c = seq.calib

    def header(t: int, i: int) -> Any:
        return T['std_msgs/msg/Header'](seq=i, stamp=T['builtin_interfaces/msg/Time'](
            sec=t // 1_000_000_000, nanosec=t % 1_000_000_000), frame_id='dvs')

    records: list[tuple[int, str, bytes]] = []
    ev = seq.events
    for i, start in enumerate(range(0, len(ev), events_per_message)):
        part = ev[start:start + events_per_message]
        shifted = EventArray(part.t + t_offset_ns, part.x, part.y, part.p)
        stamp = int(shifted.t[-1])
        records.append((stamp, EVENTS_TOPIC, encode_dvs_ros1(
            shifted, stamp_ns=stamp, seq=i, frame_id='dvs', width=c.width, height=c.height)))
    if seq.imu is not None:
        V = T['geometry_msgs/msg/Vector3']
        for i, (t, a, g) in enumerate(zip(seq.imu.t.tolist(), seq.imu.acc.tolist(),
                                          seq.imu.gyro.tolist(), strict=True)):
            t += t_offset_ns
            m = T['sensor_msgs/msg/Imu'](
                header=header(t, i), orientation=T['geometry_msgs/msg/Quaternion'](0, 0, 0, 1),
                orientation_covariance=np.zeros(9), angular_velocity=V(*g),
                angular_velocity_covariance=np.zeros(9), linear_acceleration=V(*a),
                linear_acceleration_covariance=np.zeros(9))
            records.append((t, IMU_TOPIC, bytes(ts.serialize_ros1(m, 'sensor_msgs/msg/Imu'))))
    if seq.groundtruth is not None:
        gt = seq.groundtruth
        for i, (t, p, q) in enumerate(zip(gt.t.tolist(), gt.pos.tolist(), gt.quat.tolist(),
                                          strict=True)):
            t += t_offset_ns
            m = T['geometry_msgs/msg/PoseStamped'](header=header(t, i), pose=T[
                'geometry_msgs/msg/Pose'](position=T['geometry_msgs/msg/Point'](*p),
                                          orientation=T['geometry_msgs/msg/Quaternion'](*q)))
            records.append((t, POSE_TOPIC,
                            bytes(ts.serialize_ros1(m, 'geometry_msgs/msg/PoseStamped'))))
    t0 = int(ev.t[0]) + t_offset_ns if len(ev) else t_offset_ns
    info = T['sensor_msgs/msg/CameraInfo'](
        header=header(t0, 0), height=c.height, width=c.width, distortion_model='plumb_bob',
        D=np.array(c.dist, np.float64),
        K=np.array([c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1], np.float64),
        R=np.eye(3).ravel(), P=np.array([c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0],
                                        np.float64),
        binning_x=0, binning_y=0, roi=T['sensor_msgs/msg/RegionOfInterest'](0, 0, 0, 0, False))
    records.append((t0, CAMERA_INFO_TOPIC,
                    bytes(ts.serialize_ros1(info, 'sensor_msgs/msg/CameraInfo'))))
    records.sort(key=lambda r: r[0])
    types = {EVENTS_TOPIC: DVS_TYPE, IMU_TOPIC: 'sensor_msgs/msg/Imu',
             POSE_TOPIC: 'geometry_msgs/msg/PoseStamped',
             CAMERA_INFO_TOPIC: 'sensor_msgs/msg/CameraInfo'}
    with Writer(path) as w:
        conns = {topic: w.add_connection(topic, types[topic], typestore=ts)
                 for topic in sorted({r[1] for r in records})}
        for t, topic, raw in records:
            w.write(conns[topic], t, raw)
    return path
