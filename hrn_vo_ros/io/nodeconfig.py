"""Node-only settings of the packetizer and resonator nodes (frames, QoS depths, rates).

The algorithm settings live in the stage configs (``PacketizerConfig``, ``ResonatorConfig``);
these dataclasses hold what only a running node needs. Both kinds are declared as ROS parameters
of the node, top-level, with the same names as the fields (``nodes/params.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

from hrn_vo_ros.core.clock import ClockConfig
from hrn_vo_ros.core.configbase import nested, param, validate
from hrn_vo_ros.core.odometry.odometry import OdometryConfig
from hrn_vo_ros.errors import ConfigError


@dataclass(frozen=True, slots=True)
class PacketizerNodeConfig:
    """Settings of ``packetizer_node`` besides the packetizer's own."""

    frame_id: str = param('event_camera_optical_frame', 'frame_id of the published frames')
    events_depth: int = param(1000, 'Queue depth of the event subscription (packets)',
                              lo=1, hi=100000, read_only=True)
    events_reliable: bool = param(False, 'Subscribe to events RELIABLE (lossless replay) '
                                  'instead of BEST_EFFORT as camera drivers publish',
                                  read_only=True)
    events_keep_all: bool = param(False, 'KEEP_ALL event subscription: with events_reliable, a '
                                  'KEEP_ALL player (max rate) is paced by this node',
                                  read_only=True)
    frames_depth: int = param(1000, 'Queue depth of the published frames (RELIABLE)',
                              lo=1, hi=100000, read_only=True)
    camera_info_wait_events: int = param(20_000_000, 'With rectify and no calib.* parameters: '
                                         'events held until the first camera_info (older ones '
                                         'are dropped and counted)', lo=0, hi=1_000_000_000)
    diagnostics_period_s: float = param(1.0, 'Period of the diagnostics message, seconds',
                                        lo=0.01, hi=3600.0, read_only=True)
    log_throttle_s: float = param(5.0, 'Minimum time between two warnings of one kind, seconds',
                                  lo=0.0, hi=3600.0)
    sensor_size: str = param('config', 'Sensor size: config (sensor_width/sensor_height; a '
                             'message of another size warns) or messages (EventPacket '
                             'width/height of the first packet)', choices=('config', 'messages'),
                             read_only=True)
    diagnostics_window_s: float = param(10.0, 'Diagnostics WARN while a message was rejected '
                                        'within this many seconds (wall time)', lo=0.0,
                                        hi=1e6)
    clock: ClockConfig = nested(ClockConfig, 'Sensor time to the header clock of the event '
                                'packets (output stamps, resets)')

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, slots=True)
class ResonatorNodeConfig:
    """Settings of ``resonator_node`` besides the resonator's own.

    The IMU switch is the resonator's ``imu.enabled`` (with ``focal_px`` and
    ``imu.camera_from_imu``): when true the node subscribes to ``~/imu``.
    """

    odom_frame_id: str = param('odom', 'Parent frame of the odometry (REP-105)')
    base_frame_id: str = param('base_link', 'Child frame when odometry.child_frame = base_link')
    camera_frame_id: str = param('event_camera_optical_frame',
                                 'Child frame when odometry.child_frame = camera')
    publish_tf: bool = param(False, 'Also publish odom -> child on /tf (off when a filter such '
                             'as robot_localization owns that transform)')
    map_image_rate_hz: float = param(2.0, 'Rate of ~/map_image and ~/readout_image, Hz '
                                     '(0 = never)', lo=0.0, hi=1000.0)
    seed: int = param(0, 'Seed of the random initial states (as hrn-vo run --seed)', lo=0,
                      hi=2**31 - 1, read_only=True)
    imu_buffer_samples: int = param(20000, 'Bound of the gyro buffer, samples (imu.enabled)',
                                    lo=4, hi=10_000_000, read_only=True)
    imu_depth: int = param(1000, 'Queue depth of the IMU subscription, samples', lo=1,
                           hi=1_000_000, read_only=True)
    imu_reliable: bool = param(False, 'Subscribe to the IMU RELIABLE and KEEP_ALL (lossless '
                               'max-rate replay; drivers publish best effort)', read_only=True)
    imu_timeout_s: float = param(0.5, 'When no IMU sample arrived for this long (wall time), '
                                 'frames waiting for IMU are processed with what has arrived '
                                 '(end of the IMU stream)', lo=0.0, hi=3600.0)
    max_pending_frames: int = param(200, 'Frames held while waiting for IMU samples that cover '
                                    'them; beyond this the oldest is processed anyway',
                                    lo=1, hi=100000, read_only=True)
    frames_depth: int = param(1000, 'Queue depth of the frame subscription (RELIABLE, keep '
                              'last): when the resonator falls behind, the oldest waiting frame '
                              'is dropped (counted: seq_gaps), so the odometry lags by at most '
                              'about this many frames (live.yaml: 10; replays that must keep '
                              'every frame: large)',
                              lo=1, hi=100000, read_only=True)
    diagnostics_period_s: float = param(1.0, 'Period of the diagnostics message, seconds',
                                        lo=0.01, hi=3600.0, read_only=True)
    log_throttle_s: float = param(5.0, 'Minimum time between two warnings of one kind, seconds',
                                  lo=0.0, hi=3600.0)
    imu_frame_id: str = param('', 'frame_id the IMU messages must carry (REP-145: data in the '
                              "IMU's own frame, rotated to the camera by imu.camera_from_imu; "
                              'empty: not checked, no transform)')
    publish_static_tf: bool = param(True, 'Publish base_frame_id -> camera_frame_id (from '
                                    'odometry.mount_*) and camera -> imu_frame_id on /tf_static',
                                    read_only=True)
    clock_tolerance_s: float = param(0.01, 'Frame or IMU stamps going back by more than this '
                                     'restart their time state (counted), seconds', lo=0.0,
                                     hi=1e6)
    lost_variance: float = param(1e6, 'Pose and twist variance while tracking is lost '
                                 '(a filter then effectively ignores the measurement)',
                                 lo=0.0, hi=1e18)
    min_quality: float = param(0.05, 'Quality floor: the covariance is divided by '
                               'max(quality, min_quality)^2', lo=1e-6, hi=1.0)
    diagnostics_window_s: float = param(10.0, 'Diagnostics WARN while a message was rejected '
                                        'within this many seconds (wall time)', lo=0.0,
                                        hi=1e6)
    frame_size: str = param('parameters', 'Frame size of the resonator: parameters (width/'
                            'height; frames of another size are dropped, ERROR naming what to '
                            'set) or frames (the size of the first frame, and of any later '
                            'frame of another size, which restarts tracking; a canvas given '
                            'by codebook.canvas_scale follows)', choices=('parameters', 'frames'),
                            read_only=True)
    odometry: OdometryConfig = nested(OdometryConfig, 'Calibration to metres/radians and '
                                      'the covariance model')

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, slots=True)
class RecorderNodeConfig:
    """Settings of ``bag_recorder`` (records topics as raw CDR into a ROS 2 bag)."""

    output: str = param('', 'Bag directory to create (must not exist)', read_only=True)
    storage: str = param('mcap', 'Bag storage', choices=('mcap', 'sqlite3'), read_only=True)
    topics: tuple[str, ...] = param((), 'Topics to record as TOPIC:TYPE, e.g. '
                                    '/resonator_node/odom:nav_msgs/msg/Odometry',
                                    read_only=True)
    depth: int = param(1000, 'Queue depth of each subscription (RELIABLE)', lo=1, hi=100000,
                       read_only=True)
    diagnostics_period_s: float = param(1.0, 'Period of the diagnostics message, seconds',
                                        lo=0.01, hi=3600.0, read_only=True)

    def __post_init__(self) -> None:
        validate(self)
        for spec in self.topics:
            topic, _, msgtype = spec.partition(':')
            if not topic.startswith('/') or msgtype.count('/') != 2:
                raise ConfigError(f'RecorderNodeConfig.topics entry {spec!r} is not '
                                  'TOPIC:pkg/msg/Type with an absolute topic')
