"""rclpy messages ↔ numpy/core values: the only I/O module that imports ROS message classes.

Topics and types of the node graph:

* frames: ``sensor_msgs/Image``, ``mono8``, one byte per pixel, 0 or 255, ``header.stamp`` =
  the frame (packet midpoint) time in the **header clock** of the event packets (ROS time for a
  live driver; see ``core/clock.py``).
* raw readouts (``~/readout``): ``sensor_msgs/JointState`` — a standard, stamped, labelled
  vector that rqt_plot/PlotJuggler understand. ``name = ['h', 'v', 'r'(, 'z')]``, ``position`` =
  the readout values (h, v in downsampled pixels, r in radians, z log scale), ``effort`` = the
  per-factor readout confidence (0..1), ``velocity`` empty; ``header.stamp`` = frame time.
  The resonator node appends two more names: ``quality`` (tracking quality, 0..1) and ``state``
  (tracking state code: 0 tracking, 1 degraded, 2 lost, the index in :data:`READOUT_STATES`),
  their ``effort`` NaN.
* ``~/camera_info`` of the packetizer: ``sensor_msgs/CameraInfo`` (``plumb_bob``, or no model
  with no coefficients) → :class:`~hrn_vo_ros.core.events.sequence.CameraCalibration`.
* ``~/pose`` (PoseStamped), ``~/odom`` (Odometry), ``/tf`` (TFMessage) from an
  :class:`~hrn_vo_ros.core.odometry.odometry.OdomPose`; images of the map/readout as ``mono8``.

Every decoder raises :class:`~hrn_vo_ros.errors.DecodeError` on malformed input, so nodes count
and log it instead of crashing. No function here needs ``rclpy.init``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import importlib
import math
from typing import Any, TYPE_CHECKING

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import Odometry
import numpy as np
from numpy.typing import NDArray
from sensor_msgs.msg import Image, JointState
from tf2_msgs.msg import TFMessage

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import (
    calibration_from_camera_info,
    camera_focal,
    CameraCalibration,
    CameraFocal,
)
from hrn_vo_ros.core.odometry.odometry import OdomPose, quat_from_matrix, Twist
from hrn_vo_ros.core.odometry.publish import child_frame_id, StaticFrame
from hrn_vo_ros.errors import DecodeError
from hrn_vo_ros.io.estimates import STATES as READOUT_STATES
from hrn_vo_ros.io.eventpacket import PacketDecoder

if TYPE_CHECKING:
    from hrn_vo_ros.core.live import Step

LEVELS = {'ok': DiagnosticStatus.OK, 'warn': DiagnosticStatus.WARN,
          'error': DiagnosticStatus.ERROR, 'stale': DiagnosticStatus.STALE}


def ns_to_stamp(t_ns: int) -> Time:
    """A ``builtin_interfaces/Time`` for int64 nanoseconds (non-negative)."""
    if t_ns < 0:
        raise DecodeError(f'time {t_ns} ns is negative; ROS stamps start at 0')
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nsec)


def stamp_to_ns(stamp: Any) -> int:
    """Int64 nanoseconds of a ``builtin_interfaces/Time``."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def events_from_packet(msg: Any, decoder: PacketDecoder) -> EventArray:
    """Decode an ``event_camera_msgs/EventPacket`` (mono, evt3) into events (sensor time).

    Args:
        msg: The message.
        decoder: The topic's stateful decoder (evt3 carries time state across packets).

    Raises:
        DecodeError: on an unknown encoding or a corrupt payload.
    """
    return decoder.decode(str(msg.encoding), np.frombuffer(msg.events, np.uint8),
                          time_base=int(msg.time_base), is_bigendian=bool(msg.is_bigendian))


class PacketReader:
    """The ``event_camera_msgs/EventPacket`` messages of one topic, with its stateful decoder."""

    def __init__(self) -> None:
        self.decoder = PacketDecoder()

    def read(self, msg: Any) -> tuple[int, EventArray]:
        """``(header stamp ns, events)`` of a packet.

        Raises:
            DecodeError, ValueError, TypeError, OverflowError: on a malformed packet
                (``core.events.stream.DECODE_ERRORS``).
        """
        ev = events_from_packet(msg, self.decoder)
        return stamp_to_ns(msg.header.stamp), ev

    def reread(self, msg: Any) -> EventArray | None:
        """Reset the decoder's stream state (a clock reset) and decode ``msg`` again from it.

        Returns None for an encoding without stream state (the first decoding stands).
        """
        self.decoder.reset()
        if str(msg.encoding) != 'evt3':
            return None
        return events_from_packet(msg, self.decoder)

    @staticmethod
    def size(msg: Any) -> tuple[int, int]:
        """The sensor width and height a packet gives (0 when it gives none)."""
        return int(msg.width), int(msg.height)


def frame_to_image(image: NDArray[np.uint8], t_ns: int, frame_id: str) -> Image:
    """A binary frame (0/1) as a ``mono8`` Image with values 0/255.

    Shapes:
        image: (H, W) uint8 with values 0 or 1.
    """
    h, w = image.shape
    msg = Image(height=h, width=w, encoding='mono8', is_bigendian=0, step=w)
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    msg.data = (image.astype(np.uint8, copy=False) * np.uint8(255)).tobytes()
    return msg


def camera_info_to_calibration(msg: Any) -> CameraCalibration:
    """The calibration in a ``sensor_msgs/CameraInfo`` (of rclpy or a bag reader;
    ``core.events.sequence.calibration_from_camera_info``).

    Raises:
        DecodeError: for an uncalibrated camera (zero focal length), an unsupported model or a
            bad size.
    """
    return calibration_from_camera_info(int(msg.width), int(msg.height), list(msg.k),
                                        list(msg.d), str(msg.distortion_model))


def camera_info_focal(msg: Any) -> CameraFocal:
    """``(fx, (width, height))`` of a ``sensor_msgs/CameraInfo`` (of rclpy or a bag reader):
    the focal length in sensor pixels and the sensor size, any distortion model (the resonator
    needs no more; ``core.live.camera_focal``).

    Raises:
        DecodeError: for an uncalibrated camera (fx not a positive number) or a bad size.
    """
    return camera_focal(float(msg.k[0]), int(msg.width), int(msg.height))


def image_to_frame(msg: Any) -> tuple[int, NDArray[np.uint8]]:
    """``(t_ns, image)`` of a ``mono8``/``8UC1`` frame message, image values 0/1.

    Shapes:
        image: (H, W) uint8.

    Raises:
        DecodeError: on another encoding, a size mismatch or pixel values other than 0/255.
    """
    if msg.encoding not in ('mono8', '8UC1'):
        raise DecodeError(f'frame encoding {msg.encoding!r} is not supported; publish mono8')
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.frombuffer(msg.data, np.uint8)
    if h <= 0 or w <= 0 or step < w or data.size != h * step:
        raise DecodeError(f'frame of {h}x{w} with step {step} carries {data.size} bytes')
    image = data.reshape(h, step)[:, :w]
    if np.any((image != 0) & (image != 255)):
        raise DecodeError('frame pixels must be 0 or 255 (binary event frames)')
    return stamp_to_ns(msg.header.stamp), (image > 0).astype(np.uint8)


def float_image_to_mono8(image: NDArray[np.floating[Any]], t_ns: int, frame_id: str) -> Image:
    """A real image scaled min..max to 0..255 as ``mono8`` (map and readout visualisation).

    Shapes:
        image: (H, W) float.
    """
    img = np.nan_to_num(np.asarray(image, dtype=np.float64))
    lo, hi = float(img.min(initial=0.0)), float(img.max(initial=0.0))
    scaled = np.zeros(img.shape, np.uint8) if hi <= lo else np.round(
        (img - lo) * (255.0 / (hi - lo))).astype(np.uint8)
    h, w = scaled.shape
    msg = Image(height=h, width=w, encoding='mono8', is_bigendian=0, step=w)
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    msg.data = scaled.tobytes()
    return msg


def imu_to_arrays(msg: Any) -> tuple[int, NDArray[np.float64], NDArray[np.float64]]:
    """``(t_ns, gyro, acc)`` of a ``sensor_msgs/Imu`` (``t_ns`` = its header stamp, the header
    clock the frames are mapped to: ROS time for a live driver).

    Shapes:
        gyro: (3,) rad/s; acc: (3,) m/s^2.

    Raises:
        DecodeError: if the angular velocity is not finite.
    """
    w, a = msg.angular_velocity, msg.linear_acceleration
    gyro = np.array([w.x, w.y, w.z], dtype=np.float64)
    acc = np.array([a.x, a.y, a.z], dtype=np.float64)
    if not np.all(np.isfinite(gyro)):
        raise DecodeError(f'IMU angular velocity {gyro.tolist()} is not finite')
    return stamp_to_ns(msg.header.stamp), gyro, acc


def pose_to_pose_stamped(pose: OdomPose, frame_id: str) -> PoseStamped:
    """``geometry_msgs/PoseStamped`` of a pose in ``frame_id``."""
    msg = PoseStamped()
    msg.header.stamp = ns_to_stamp(pose.t_ns)
    msg.header.frame_id = frame_id
    p, q = msg.pose.position, msg.pose.orientation
    p.x, p.y, p.z = (float(c) for c in pose.position)
    q.x, q.y, q.z, q.w = (float(c) for c in pose.quat)
    return msg


def pose_to_odometry(pose: OdomPose, frame_id: str, child_frame_id: str,
                     twist_variance: float, twist: Twist | None = None) -> Odometry:
    """``nav_msgs/Odometry`` with the pose covariance and the twist (in the child frame).

    Without ``twist`` it is zero with ``twist_variance`` on its diagonal (unknown, not
    "exactly zero").
    """
    msg = Odometry()
    msg.header.stamp = ns_to_stamp(pose.t_ns)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    p.x, p.y, p.z = (float(c) for c in pose.position)
    q.x, q.y, q.z, q.w = (float(c) for c in pose.quat)
    msg.pose.covariance = np.ascontiguousarray(pose.covariance, np.float64).reshape(36)
    if twist is None:
        msg.twist.covariance = (np.eye(6) * twist_variance).reshape(36)
        return msg
    lin, ang = msg.twist.twist.linear, msg.twist.twist.angular
    lin.x, lin.y, lin.z = (float(c) for c in twist.linear)
    ang.x, ang.y, ang.z = (float(c) for c in twist.angular)
    msg.twist.covariance = np.ascontiguousarray(twist.covariance, np.float64).reshape(36)
    return msg


def static_transform(t_ns: int, frame_id: str, child_frame_id: str,
                     rotation: NDArray[np.float64],
                     translation: NDArray[np.float64]) -> TransformStamped:
    """A ``geometry_msgs/TransformStamped`` ``frame_id`` → ``child_frame_id`` (for /tf_static).

    Shapes:
        rotation: (3, 3), the child's axes in the parent; translation: (3,) metres.
    """
    tf = TransformStamped()
    tf.header.stamp = ns_to_stamp(t_ns)
    tf.header.frame_id = frame_id
    tf.child_frame_id = child_frame_id
    t, q = tf.transform.translation, tf.transform.rotation
    t.x, t.y, t.z = (float(c) for c in translation)
    q.x, q.y, q.z, q.w = (float(c) for c in quat_from_matrix(np.asarray(rotation, np.float64)))
    return tf


def static_transforms(t_ns: int, frames: Sequence[StaticFrame]) -> TFMessage:
    """The ``/tf_static`` message of ``(parent, child, rotation, translation)`` transforms."""
    return TFMessage(transforms=[static_transform(t_ns, parent, child, R, t)
                                 for parent, child, R, t in frames])


def pose_to_tf(pose: OdomPose, frame_id: str, child_frame_id: str) -> TFMessage:
    """A ``tf2_msgs/TFMessage`` with the one transform ``frame_id`` → ``child_frame_id``."""
    tf = TransformStamped()
    tf.header.stamp = ns_to_stamp(pose.t_ns)
    tf.header.frame_id = frame_id
    tf.child_frame_id = child_frame_id
    t, q = tf.transform.translation, tf.transform.rotation
    t.x, t.y, t.z = (float(c) for c in pose.position)
    q.x, q.y, q.z, q.w = (float(c) for c in pose.quat)
    return TFMessage(transforms=[tf])


def readout_to_joint_state(t_ns: int, values: Mapping[str, float],
                           confidence: Mapping[str, float], *, quality: float | None = None,
                           state: str | None = None) -> JointState:
    """The raw readout topic message (see the module docstring).

    Args:
        t_ns: Frame time (the header stamp).
        values: Readout values by factor name (h, v, r [, z]).
        confidence: Per-factor confidence (NaN where missing).
        quality: Tracking quality in [0, 1], appended as the name ``quality``, or None.
        state: Tracking state (:data:`READOUT_STATES`), appended as the name ``state`` with its
            code (the index), or None.

    Raises:
        DecodeError: for a state outside :data:`READOUT_STATES`.
    """
    msg = JointState()
    msg.header.stamp = ns_to_stamp(t_ns)
    names = list(values)
    position = [float(values[k]) for k in names]
    effort = [float(confidence.get(k, math.nan)) for k in names]
    if quality is not None:
        names.append('quality')
        position.append(float(quality))
        effort.append(math.nan)
    if state is not None:
        if state not in READOUT_STATES:
            raise DecodeError(f'tracking state {state!r} is not one of '
                              f'{", ".join(READOUT_STATES)}')
        names.append('state')
        position.append(float(READOUT_STATES.index(state)))
        effort.append(math.nan)
    msg.name = names
    msg.position = position
    msg.effort = effort
    return msg


def step_messages(step: Step, frame_id: str, base_frame_id: str, camera_frame_id: str, *,
                  with_tf: bool) -> list[JointState | PoseStamped | Odometry | TFMessage]:
    """The readout, pose, odometry and (``with_tf``) tf messages of one processed frame.

    The child frame is ``base_frame_id`` or ``camera_frame_id`` by ``odometry.child_frame``.
    """
    est, out = step.estimate, step.out
    child = child_frame_id(step.odometry, base_frame_id, camera_frame_id)
    readout = readout_to_joint_state(step.t_ns, out.values, est.confidence,
                                     quality=est.quality, state=est.state)
    odom = pose_to_odometry(out.pose, frame_id, child, step.odometry.unobserved_variance,
                            out.twist)
    msgs = [readout, pose_to_pose_stamped(out.pose, frame_id), odom]
    return (msgs + [pose_to_tf(out.pose, frame_id, child)]) if with_tf else msgs


def joint_state_to_readout(msg: Any) -> tuple[int, dict[str, float], dict[str, float]]:
    """``(t_ns, values, confidence)`` of a raw readout message."""
    names = list(msg.name)
    pos, eff = list(msg.position), list(msg.effort)
    if len(pos) != len(names):
        raise DecodeError(f'readout names {names} and positions {pos} differ in length')
    conf = dict(zip(names, eff, strict=True)) if len(eff) == len(names) else {}
    return stamp_to_ns(msg.header.stamp), dict(zip(names, pos, strict=True)), conf


def diagnostics(t_ns: int, name: str, hardware_id: str, level: str, message: str,
                values: Sequence[tuple[str, object]]) -> DiagnosticArray:
    """A ``DiagnosticArray`` with one status (level ``ok``/``warn``/``error``/``stale``)."""
    status = DiagnosticStatus(level=LEVELS[level], name=name, message=message,
                              hardware_id=hardware_id)
    status.values = [KeyValue(key=k, value=str(v)) for k, v in values]
    msg = DiagnosticArray(status=[status])
    msg.header.stamp = ns_to_stamp(t_ns)
    return msg


def diagnostic_values(msg: Any) -> dict[str, str]:
    """The key/values of the first status of a ``DiagnosticArray`` (for tests and tools)."""
    if not msg.status:
        return {}
    return {kv.key: kv.value for kv in msg.status[0].values}


def message_class(msgtype: str) -> Any:
    """The rclpy message class of ``pkg/msg/Name``.

    Raises:
        DecodeError: if the package or message is not installed.
    """
    pkg, kind, name = (msgtype.split('/') + ['', ''])[:3]
    try:
        return getattr(importlib.import_module(f'{pkg}.{kind}'), name)
    except (ImportError, AttributeError, ValueError) as err:
        raise DecodeError(f'message type {msgtype!r} is not installed ({err})') from err
