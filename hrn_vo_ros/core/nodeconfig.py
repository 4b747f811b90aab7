"""Node-only settings of the packetizer and resonator nodes (frames, QoS depths, rates).

The algorithm settings live in the stage configs (``PacketizerConfig``, ``ResonatorConfig``);
these dataclasses hold what only a running node needs. Both kinds are declared as ROS parameters
of the node, top-level, with the same names as the fields (``nodes/params.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

from hrn_vo_ros.core.configbase import nested, param, validate
from hrn_vo_ros.core.odometry import OdometryConfig


@dataclass(frozen=True, slots=True)
class PacketizerNodeConfig:
    """Settings of ``packetizer_node`` besides the packetizer's own."""

    frame_id: str = param('event_camera_optical_frame', 'frame_id of the published frames')
    events_depth: int = param(1000, 'Queue depth of the event subscription (packets)',
                              lo=1, hi=100000, read_only=True)
    events_reliable: bool = param(False, 'Subscribe to events RELIABLE (lossless replay) '
                                  'instead of BEST_EFFORT as camera drivers publish',
                                  read_only=True)
    frames_depth: int = param(1000, 'Queue depth of the published frames (RELIABLE)',
                              lo=1, hi=100000, read_only=True)
    diagnostics_period_s: float = param(1.0, 'Period of the diagnostics message, seconds',
                                        lo=0.01, hi=3600.0, read_only=True)
    log_throttle_s: float = param(5.0, 'Minimum time between two warnings of one kind, seconds',
                                  lo=0.0, hi=3600.0)

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, slots=True)
class ResonatorNodeConfig:
    """Settings of ``resonator_node`` besides the resonator's own."""

    odom_frame_id: str = param('odom', 'Parent frame of the odometry (REP-105)')
    base_frame_id: str = param('base_link', 'Child frame when odometry.child_frame = base_link')
    camera_frame_id: str = param('event_camera_optical_frame',
                                 'Child frame when odometry.child_frame = camera')
    publish_tf: bool = param(False, 'Also publish odom -> child on /tf (off when a filter such '
                             'as robot_localization owns that transform)')
    map_image_rate_hz: float = param(2.0, 'Rate of ~/map_image and ~/readout_image, Hz '
                                     '(0 = never)', lo=0.0, hi=1000.0)
    use_imu: bool = param(False, 'Subscribe to ~/imu and fuse the gyro (prediction step)',
                          read_only=True)
    imu_buffer_s: float = param(2.0, 'Length of the gyro buffer, seconds of sensor time',
                                lo=0.01, hi=600.0, read_only=True)
    max_pending_frames: int = param(200, 'Frames held while waiting for IMU samples that cover '
                                    'them; beyond this the oldest is processed without',
                                    lo=1, hi=100000, read_only=True)
    frames_depth: int = param(1000, 'Queue depth of the frame subscription (RELIABLE)',
                              lo=1, hi=100000, read_only=True)
    diagnostics_period_s: float = param(1.0, 'Period of the diagnostics message, seconds',
                                        lo=0.01, hi=3600.0, read_only=True)
    log_throttle_s: float = param(5.0, 'Minimum time between two warnings of one kind, seconds',
                                  lo=0.0, hi=3600.0)
    odometry: OdometryConfig = nested(OdometryConfig, 'Calibration to metres/radians and '
                                      'the covariance model')

    def __post_init__(self) -> None:
        validate(self)
