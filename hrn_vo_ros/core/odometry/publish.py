"""The publisher side of the odometry: what ``resonator_node`` makes of each estimate.

* :class:`OdometryComposer`: an :class:`~hrn_vo_ros.core.odometry.estimate.Estimate` → the
  readout values, the pose and the twist (finite difference of consecutive poses) with
  covariances that follow the tracking state: divided by ``max(quality, min_quality)²`` (they
  grow as quality falls) and ``lost_variance`` on the diagonal while lost (a filter then
  effectively ignores the measurement). It keeps the tracking state for the diagnostics and
  reconciles the odometry focal length with the resonator's ``focal_px``.
* :class:`GyroGate`: frames wait, bounded, until the gyro covers them (then their gyro
  increment is final); all go when forced (a time reset, the IMU stopped).
* :func:`static_frames`: the static transforms (base → camera mount, camera → IMU).
* the texts of the node's frame-size and IMU-frame checks.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.core.odometry.odometry import (
    mount_transform,
    OdometryConfig,
    OdomPose,
    readout_to_pose,
    Twist,
    twist_between,
)

#: A static transform: parent frame, child frame, rotation (3, 3), translation (3,) metres.
StaticFrame = tuple[str, str, NDArray[np.float64], NDArray[np.float64]]


def static_frames(odo: OdometryConfig, camera_from_imu: NDArray[np.float64] | tuple[float, ...],
                  *, base: str, camera: str, imu: str = '') -> list[StaticFrame]:
    """``base`` → ``camera`` from the mount of ``odo`` and, with an ``imu`` frame, ``camera``
    → ``imu`` rotated by ``camera_from_imu`` (9 values, row-major)."""
    R, t = mount_transform(odo)
    frames: list[StaticFrame] = [(base, camera, R, t)]
    if imu:
        R_ci = np.reshape(np.asarray(camera_from_imu, np.float64), (3, 3))
        frames.append((camera, imu, R_ci, np.zeros(3)))
    return frames


def child_frame_id(odo: OdometryConfig, base: str, camera: str) -> str:
    """The child frame of the odometry: ``base`` or ``camera`` by ``odo.child_frame``."""
    return base if odo.child_frame == 'base_link' else camera


def with_covariance_scale(pose: OdomPose, twist: Twist | None, quality: float, state: str, *,
                          lost_variance: float, min_quality: float
                          ) -> tuple[OdomPose, Twist | None]:
    """Covariances that grow as quality falls, ``lost_variance`` while lost."""
    if state == 'lost':
        cov = np.eye(6) * lost_variance
        pose = OdomPose(pose.t_ns, pose.position, pose.quat, cov)
        return pose, None if twist is None else Twist(twist.linear, twist.angular, cov)
    q = quality if np.isfinite(quality) else 0.0
    k = 1.0 / max(min(q, 1.0), min_quality) ** 2
    if k == 1.0:
        return pose, twist
    pose = OdomPose(pose.t_ns, pose.position, pose.quat, pose.covariance * k)
    if twist is not None:
        twist = Twist(twist.linear, twist.angular, twist.covariance * k)
    return pose, twist


@dataclass(frozen=True, slots=True, eq=False)
class Composed:
    """What one estimate publishes: readout values by factor, the pose, the twist (or None)."""

    values: dict[str, float]
    pose: OdomPose
    twist: Twist | None


class OdometryComposer:
    """Estimates → poses and twists with honest covariances (see the module docstring)."""

    def __init__(self) -> None:
        self.prev_pose: OdomPose | None = None
        self.quality, self.state = 1.0, 'tracking'
        self.confidence: Mapping[str, float] = {}
        self._key: tuple[OdometryConfig, float] | None = None
        self._odo: OdometryConfig | None = None

    def odometry(self, odo: OdometryConfig, focal_px: float) -> tuple[OdometryConfig, str | None]:
        """``odo`` with the resonator's ``focal_px`` (when set) as the one focal length.

        Returns:
            The odometry settings and, the first time a pair differs, a warning text.
        """
        if self._key == (odo, focal_px) and self._odo is not None:
            return self._odo, None
        self._key = (odo, focal_px)
        warning = None
        if focal_px > 0.0 and abs(odo.focal_length_px - focal_px) > 1e-9 * focal_px:
            warning = (f'focal_px {focal_px:g} and odometry.focal_length_px '
                       f'{odo.focal_length_px:g} differ: the odometry uses focal_px (one focal '
                       'length for every stage)')
            odo = replace(odo, focal_length_px=focal_px)
        self._odo = odo
        return odo, warning

    def restart(self) -> None:
        """Tracking or time restarted: the next pose has no twist."""
        self.prev_pose = None

    def compose(self, t_ns: int, est: Estimate, odo: OdometryConfig, *, with_z: bool,
                lost_variance: float, min_quality: float) -> Composed:
        """The values, pose and twist of ``est`` of the frame at ``t_ns`` (the previous pose
        kept for the next twist)."""
        values = {'h': est.h, 'v': est.v, 'r': est.r}
        if with_z:
            values['z'] = est.z
        self.confidence = est.confidence
        pose = readout_to_pose(odo, t_ns, est.h, est.v, est.r,
                               est.z if with_z else None, est.confidence)
        twist = None if self.prev_pose is None else twist_between(
            self.prev_pose, pose, odo.unobserved_variance)
        self.prev_pose = pose
        self.quality, self.state = float(est.quality), str(est.state)
        pose, twist = with_covariance_scale(pose, twist, self.quality, self.state,
                                            lost_variance=lost_variance,
                                            min_quality=min_quality)
        return Composed(values, pose, twist)

    def diagnostic_values(self) -> list[tuple[str, object]]:
        """Confidence per factor, quality and tracking state for the diagnostics."""
        out: list[tuple[str, object]] = [
            (f'confidence_{k}', f'{v:.3f}') for k, v in sorted(self.confidence.items())]
        return out + [('quality', f'{self.quality:.3f}'), ('tracking_state', self.state)]

    def status(self) -> tuple[str, str]:
        """``(level, message)``: ERROR while lost, WARN while degraded, else OK."""
        level = 'error' if self.state == 'lost' else 'warn' if self.state == 'degraded' else 'ok'
        return level, f'tracking {self.state} (quality {self.quality:.2f})'


class GyroGate:
    """Frames waiting, bounded, for the gyro samples that cover them.

    Args:
        camera_from_imu: The IMU → camera rotation (9 values, row-major).
        max_samples: Bound of the gyro buffer.
        max_pending: Frames held at most; beyond, the oldest goes anyway.
    """

    def __init__(self, camera_from_imu: NDArray[np.float64] | tuple[float, ...], *,
                 max_samples: int, max_pending: int) -> None:
        self._camera_from_imu = np.reshape(np.asarray(camera_from_imu, np.float64), (3, 3))
        self._max_samples = max_samples
        self.max_pending = max_pending
        self.gyro = self.new_gyro()
        self._pending: deque[tuple[int, NDArray[np.uint8], float]] = deque()
        self.last_imu_wall = 0.0

    def __len__(self) -> int:
        return len(self._pending)

    def new_gyro(self, camera_from_imu: NDArray[np.float64] | tuple[float, ...] | None = None
                 ) -> GyroIntegrator:
        """Start a new, empty gyro integrator (a time reset) and return it.

        Args:
            camera_from_imu: The rotation from now on (None: the one before).
        """
        if camera_from_imu is not None:
            self._camera_from_imu = np.reshape(np.asarray(camera_from_imu, np.float64), (3, 3))
        self.gyro = GyroIntegrator(self._camera_from_imu, max_samples=self._max_samples)
        return self.gyro

    def add_gyro(self, t_ns: int, gyro: NDArray[np.float64], wall: float) -> None:
        """One gyro sample (camera-rotated by the integrator), arrived at wall time ``wall``."""
        self.gyro.add(t_ns, gyro)
        self.last_imu_wall = wall

    def add(self, t_ns: int, image: NDArray[np.uint8], wall: float) -> None:
        """A frame that waits, arrived at wall time ``wall``."""
        self._pending.append((t_ns, image, wall))

    def stalled(self, now: float, timeout_s: float) -> bool:
        """Whether frames wait and neither they nor the IMU moved for ``timeout_s``."""
        return bool(self._pending) and min(now - self._pending[0][2],
                                           now - self.last_imu_wall) > timeout_s

    def drain(self, *, force: bool) -> Iterator[tuple[int, NDArray[np.uint8]]]:
        """Frames whose gyro increment is final (or all when ``force``), oldest first; the
        gyro buffer is trimmed to each after the caller processed it."""
        gyro = self.gyro
        while self._pending and (force or len(self._pending) > self.max_pending
                                 or gyro.covers(self._pending[0][0])):
            t_ns, image, _ = self._pending.popleft()
            yield t_ns, image
            gyro.trim(t_ns)


def size_mismatch_text(w: int, h: int, width: int, height: int) -> str:
    """What to set when frames are ``w`` x ``h`` and the resonator takes ``width`` x ``height``.

    The usual cause is ``sensor_size: messages``: the packetizer's frame is ceil(sensor /
    downsample), which for another camera is not the resonator's fixed size (the live configs
    take the frames' size instead, ``frame_size: frames``).
    """
    return (f'frames are {w}x{h}, width/height are {width}x{height}: set the resonator '
            f'width: {w} and height: {h} (or frame_size: frames), or the packetizer downsample '
            f'so that its frame is {width}x{height} (downsample = sensor width / {width}; 0 '
            'gives at most 96x72)')


def imu_frame_warning(frame_id: str, imu_frame_id: str) -> str | None:
    """The warning for an IMU message in another frame than ``imu_frame_id`` (unset: none)."""
    if not imu_frame_id or frame_id == imu_frame_id:
        return None
    return (f'IMU message in frame {frame_id!r}, imu_frame_id is {imu_frame_id!r}: '
            'imu.camera_from_imu must rotate that frame')


__all__ = ['child_frame_id', 'Composed', 'GyroGate', 'imu_frame_warning', 'OdometryComposer',
           'size_mismatch_text', 'static_frames', 'StaticFrame', 'with_covariance_scale']
