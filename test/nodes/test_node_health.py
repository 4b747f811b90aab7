"""What the nodes tell a robot about their health, as real nodes over DDS (fast: seconds).

Diagnostics levels over the recent window (WARN while rejecting or waiting, OK again after),
the sensor size taken from the messages, the resonator's frame-size error naming what to set,
covariances scaled by tracking quality (1e6 while lost) with the level by state, and the evt3
decoder's time state restarting with the event clock.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
import math
import time
from types import SimpleNamespace
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from event_camera_msgs.msg import EventPacket
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers import spin_until
from sensor_msgs.msg import CameraInfo, Image
from test_nodes import packet, random_events

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.hrn.gyro import GyroBias
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.odometry import OdometryConfig, readout_to_pose, twist_between
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.eventpacket import encode_evt3
from hrn_vo_ros.nodes.common import qos
from hrn_vo_ros.nodes.packetizer_node import PacketizerNode
from hrn_vo_ros.nodes.resonator_node import ResonatorNode

pytestmark = pytest.mark.ros
OK, WARN, ERROR = b'\x00', b'\x01', b'\x02'
WINDOW = 0.6
PER_FRAME = 500
# plain binning (no noise floor: it would hold the short test streams for its 250 ms window)
PLAIN = Parameter('noise_floor_hz', value=0.0)


@dataclass
class Status:
    """One node's last diagnostics: level, message, values."""

    level: bytes
    message: str
    values: dict[str, str]


@dataclass
class Probe:
    """Nodes under test plus a probe node on one executor."""

    nodes: list[Node]
    node: Node = field(init=False)
    ex: SingleThreadedExecutor = field(init=False)
    diags: dict[str, list[Status]] = field(default_factory=dict)
    frames: list[Image] = field(default_factory=list)
    odoms: list[Odometry] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.node = Node('probe')
        self.ev_pub = self.node.create_publisher(EventPacket, '/packetizer_node/events',
                                                 qos(1000))
        self.frame_pub = self.node.create_publisher(Image, '/frames', qos(100))
        self.node.create_subscription(Image, '/frames', self.frames.append, qos(1000))
        self.node.create_subscription(Odometry, '/resonator_node/odom', self.odoms.append,
                                      qos(1000))
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 100)
        self.ex = SingleThreadedExecutor()
        for n in [*self.nodes, self.node]:
            self.ex.add_node(n)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        st = msg.status[0]
        self.diags.setdefault(st.name.split(':')[0], []).append(
            Status(bytes(st.level), st.message, ros_msgs.diagnostic_values(msg)))

    def last(self, node: str) -> Status | None:
        got = self.diags.get(node)
        return got[-1] if got else None

    def wait(self, cond: Callable[[], bool], timeout: float = 10.0) -> bool:
        return spin_until(self.ex, cond, timeout)

    def wait_level(self, node: str, level: bytes, timeout: float = 10.0) -> Status:
        n0 = len(self.diags.get(node, []))

        def fresh() -> bool:        # a status published after the call, at that level
            got = self.diags.get(node, [])
            return len(got) > n0 and got[-1].level == level

        assert self.wait(fresh, timeout), f'{node}: no level {level!r}; last {self.last(node)}'
        status = self.last(node)
        assert status is not None
        return status


COMMON = [Parameter('diagnostics_period_s', value=0.1),
          Parameter('diagnostics_window_s', value=WINDOW)]
REMAP = ['--ros-args', '-r', '~/frames:=/frames']


def packetizer(**params: Any) -> PacketizerNode:
    over = [Parameter('events_per_frame', value=PER_FRAME), PLAIN,
            Parameter('events_reliable', value=True), *COMMON]
    over += [Parameter(k.replace('__', '.'), value=v) for k, v in params.items()]
    return PacketizerNode(parameter_overrides=over, cli_args=REMAP)


def resonator(**params: Any) -> ResonatorNode:
    over = [*COMMON, Parameter('focal_px', value=80.0)]
    over += [Parameter(k.replace('__', '.'), value=v) for k, v in params.items()]
    return ResonatorNode(parameter_overrides=over, cli_args=REMAP)


@pytest.fixture
def ros() -> Iterator[list[Node]]:
    """rclpy for one test; nodes appended to the list are destroyed after it."""
    rclpy.init()
    made: list[Node] = []
    try:
        yield made
    finally:
        for n in made:
            n.destroy_node()
        rclpy.try_shutdown()


def start(ros: list[Node], *nodes: Node) -> Probe:
    ros.extend(nodes)
    p = Probe(list(nodes))
    ros.append(p.node)
    assert p.wait(lambda: p.ev_pub.get_subscription_count() > 0
                  or p.frame_pub.get_subscription_count() > 0)
    return p


def test_packetizer_warns_while_rejecting_and_waiting_then_ok(
        ros: list[Node], rng: np.random.Generator) -> None:
    p = start(ros, packetizer())
    p.wait_level('packetizer_node', OK)
    p.ev_pub.publish(packet(EventArray.empty(), 0))                 # rejected: empty
    st = p.wait_level('packetizer_node', WARN)
    assert 'malformed' in st.message and st.values['bad_empty'] == '1'
    t0 = time.monotonic()
    st = p.wait_level('packetizer_node', OK)                        # the window passed
    assert time.monotonic() - t0 < WINDOW + 3.0                     # bounded: the window
    assert st.values['bad_empty'] == '1'                            # the total is kept
    p.ev_pub.publish(packet(random_events(rng, 2 * PER_FRAME), 1))
    assert p.wait(lambda: len(p.frames) == 2)
    assert p.last('packetizer_node').level == OK                    # type: ignore[union-attr]


def test_packetizer_warns_while_waiting_for_camera_info(
        ros: list[Node], rng: np.random.Generator) -> None:
    p = start(ros, packetizer(rectify='pinhole'))
    st = p.wait_level('packetizer_node', WARN)
    assert 'camera_info' in st.message
    p.ev_pub.publish(packet(random_events(rng, 2 * PER_FRAME), 0))
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    info = p.node.create_publisher(CameraInfo, '/packetizer_node/camera_info', latched)
    msg = CameraInfo(width=240, height=180, distortion_model='plumb_bob')
    msg.k = [199.0, 0.0, 120.0, 0.0, 199.0, 90.0, 0.0, 0.0, 1.0]
    msg.d = [0.0] * 5
    info.publish(msg)
    assert p.wait(lambda: len(p.frames) == 2)                       # the held events
    st = p.wait_level('packetizer_node', OK)
    assert st.values['waiting_for_camera_info'] == 'False'


def sensor_packet(rng: np.random.Generator, n: int, seq: int, t0: int, w: int, h: int
                  ) -> EventPacket:
    t = t0 + np.cumsum(rng.integers(1, 2000, n))
    x = np.concatenate(([w - 1], rng.integers(0, w, n - 1)))        # the sensor's corners
    y = np.concatenate(([h - 1], rng.integers(0, h, n - 1)))
    msg = packet(EventArray.from_arrays(t, x, y, rng.integers(0, 2, n)), seq)
    msg.width, msg.height = w, h
    return msg


def test_sensor_size_from_messages_640x480(ros: list[Node], rng: np.random.Generator) -> None:
    # downsample 0 (auto, the default): 640x480 into 96x72 at 6.667
    p = start(ros, packetizer(sensor_size='messages'), resonator())
    for k in range(3):
        p.ev_pub.publish(sensor_packet(rng, 2 * PER_FRAME, k, 10**9 + k * 10**8, 640, 480))
    assert p.wait(lambda: len(p.odoms) == 6)
    assert {(f.width, f.height) for f in p.frames} == {(96, 72)}
    assert p.wait(lambda: (p.last('packetizer_node') or Status(OK, '', {})).values.get(
        'frames_out') == '6')
    st = p.last('packetizer_node')
    assert st is not None and st.level == OK
    assert (st.values['sensor_size'], st.values['frame_size']) == ('640x480', '96x72')
    assert 'bad_out_of_sensor' not in st.values


def test_frame_size_mismatch_is_an_error_naming_what_to_set(
        ros: list[Node], rng: np.random.Generator) -> None:
    # the sensor size from the messages with a fixed downsample 2.5, the resonator at 96x72
    p = start(ros, packetizer(sensor_size='messages', downsample=2.5), resonator())
    p.ev_pub.publish(sensor_packet(rng, 2 * PER_FRAME, 0, 10**9, 640, 480))
    st = p.wait_level('resonator_node', ERROR)
    assert 'frames are 256x192' in st.message and '96x72' in st.message
    assert 'width: 256' in st.message and 'downsample' in st.message
    assert st.values['bad_size'] == '2' and not p.odoms


def test_frame_size_frames_takes_the_size_of_the_frames(
        ros: list[Node], rng: np.random.Generator) -> None:
    # live.yaml: any sensor; 640x480 at downsample 5 gives 128x96 frames, then a 320x240
    # camera (a driver restarted with another sensor) 64x48 ones
    p = start(ros, packetizer(sensor_size='messages', downsample=5.0),
              resonator(frame_size='frames'))
    for k in range(3):
        p.ev_pub.publish(sensor_packet(rng, 2 * PER_FRAME, k, 10**9 + k * 10**8, 640, 480))
    assert p.wait(lambda: len(p.odoms) == 6)
    for k in range(3, 6):
        p.ev_pub.publish(sensor_packet(rng, 2 * PER_FRAME, k, 10**9 + k * 10**8, 320, 240))
    assert p.wait(lambda: len(p.odoms) == 12)
    assert [(f.width, f.height) for f in p.frames] == [(128, 96)] * 6 + [(64, 48)] * 6
    assert p.wait(lambda: (p.last('resonator_node') or Status(OK, '', {})).values.get(
        'estimates_out') == '12')
    st = p.last('resonator_node')       # random events: tracking degrades (WARN), no ERROR
    assert st is not None and st.level != ERROR and 'bad_size' not in st.values, st


def test_frame_size_frames_drops_frames_the_config_cannot_take(
        ros: list[Node], rng: np.random.Generator) -> None:
    # a fixed 100x80 canvas takes the 96x72 frames of its parameters, not 128x96 ones
    p = start(ros, packetizer(sensor_size='messages', downsample=5.0),
              resonator(frame_size='frames', codebook__canvas_width=100,
                        codebook__canvas_height=80))
    p.ev_pub.publish(sensor_packet(rng, 2 * PER_FRAME, 0, 10**9, 640, 480))
    st = p.wait_level('resonator_node', ERROR)
    assert 'frames are 128x96' in st.message and st.values['bad_size'] == '2' and not p.odoms


class Scripted:
    """An estimator whose estimates have the given quality and state, h growing by 1 px."""

    factors = ('h', 'v', 'r')
    rejected_frames = 0
    limited_frames = 0
    hot_pixels = 0
    tracker = SimpleNamespace(distinct=float('nan'), relocalisations=0, gaps=0)
    gyro_bias = GyroBias(memory_s=0.0, prior_s=3.0, max_rad_s=0.1)

    def __init__(self, script: list[tuple[float, str]]) -> None:
        self.script = script
        self.k = 0

    def map_image(self) -> np.ndarray:
        return np.zeros((72, 96))

    egocentric_map_image = map_image

    def step(self, image: Any, t_ns: int, *, gyro_delta: Any = None) -> Estimate:
        q, state = self.script[min(self.k, len(self.script) - 1)]
        self.k += 1
        return Estimate(t_ns, float(self.k), 0.0, 0.0, 0.0,
                        confidence={'h': 1.0, 'v': 1.0, 'r': 1.0}, quality=q, state=state)


def test_covariance_follows_quality_and_lost_and_the_level_the_state(ros: list[Node]) -> None:
    node = resonator(min_quality=0.05, lost_variance=1e6)
    p = start(ros, node)
    node._live.pipeline.estimator = Scripted([(1.0, 'tracking'), (1.0, 'tracking'),
                                              (0.5, 'degraded'), (0.01, 'degraded'),
                                              (0.3, 'lost'), (0.9, 'tracking')])
    cfg = OdometryConfig(focal_length_px=80.0)
    image = np.eye(72, 96, dtype=np.uint8)

    def frame(k: int) -> None:
        p.frame_pub.publish(ros_msgs.frame_to_image(image, 10**9 + k * 10**7, 'cam'))
        assert p.wait(lambda: len(p.odoms) == k + 1)

    for k in range(2):
        frame(k)
    p.wait_level('resonator_node', OK)
    raw = [readout_to_pose(cfg, 10**9 + k * 10**7, float(k + 1), 0.0, 0.0, None,
                           {'h': 1.0, 'v': 1.0, 'r': 1.0}) for k in range(6)]
    base = [r.covariance for r in raw]
    for k in range(2):
        np.testing.assert_allclose(np.reshape(p.odoms[k].pose.covariance, (6, 6)), base[k])
    frame(2)                                                 # quality 0.5: variance x 4
    np.testing.assert_allclose(np.reshape(p.odoms[2].pose.covariance, (6, 6)), 4 * base[2])
    tw = twist_between(raw[1], raw[2], cfg.unobserved_variance)
    np.testing.assert_allclose(np.reshape(p.odoms[2].twist.covariance, (6, 6)),
                               4 * tw.covariance, rtol=1e-9)
    yaw_rate = (math.atan(2 / 80) - math.atan(3 / 80)) / 0.01   # pan right = negative yaw
    assert p.odoms[2].twist.twist.angular.z == pytest.approx(yaw_rate, rel=1e-6)
    st = p.wait_level('resonator_node', WARN)
    assert 'degraded' in st.message and st.values['quality'] == '0.500'
    frame(3)                                                 # quality 0.01: floor 0.05, x 400
    np.testing.assert_allclose(np.reshape(p.odoms[3].pose.covariance, (6, 6)), 400 * base[3])
    frame(4)                                                 # lost: 1e6, pose and twist
    assert list(p.odoms[4].pose.covariance) == list((np.eye(6) * 1e6).reshape(36))
    assert list(p.odoms[4].twist.covariance) == list((np.eye(6) * 1e6).reshape(36))
    st = p.wait_level('resonator_node', ERROR)
    assert 'lost' in st.message and st.values['tracking_state'] == 'lost'
    # the diagonal frames have no 4-neighbouring on pixels: structure 0, said with the loss
    assert st.values['frame_structure'] == '0.00' and 'scattered as noise' in st.message
    frame(5)                                                 # tracking again (quality 0.9)
    np.testing.assert_allclose(np.reshape(p.odoms[5].pose.covariance, (6, 6)),
                               base[5] / 0.81, rtol=1e-9)
    p.wait_level('resonator_node', OK)


def evt3_packet(ev: EventArray, seq: int) -> EventPacket:
    msg = EventPacket(height=180, width=240, seq=seq, time_base=0, encoding='evt3',
                      is_bigendian=False)
    msg.header.stamp = ros_msgs.ns_to_stamp(int(ev.t[0]))      # header = sensor time (a bag)
    msg.events = encode_evt3(ev).tobytes()
    return msg


def test_looped_evt3_stream_restarts_the_decoder_time(ros: list[Node],
                                                      rng: np.random.Generator) -> None:
    p = start(ros, packetizer())
    n = 4 * PER_FRAME                                         # 0.2 s of events, us times
    t = 2 * 10**9 + np.cumsum(rng.integers(1, 200, n)) * 1000
    ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                rng.integers(0, 2, n))
    cuts = [0, 700, 1500, len(ev)]
    for loop in range(2):                                     # a bag played twice
        for i, (a, b) in enumerate(zip(cuts[:-1], cuts[1:], strict=True)):
            p.ev_pub.publish(evt3_packet(ev[a:b], loop * 3 + i))
        want = 4 * (loop + 1)
        assert p.wait(lambda: len(p.frames) == want), (len(p.frames), p.last(  # noqa: B023
            'packetizer_node'))
    stamps = [ros_msgs.stamp_to_ns(f.header.stamp) for f in p.frames]
    assert stamps[4:] == stamps[:4]                           # the second loop as the first
    assert p.wait(lambda: (p.last('packetizer_node') or Status(OK, '', {})).values.get(
        'frames_out') == '8')
    st = p.last('packetizer_node')
    assert st is not None
    # without the decoder reset the second loop's first TIME_HIGH reads as a rollover of the
    # first loop's clock (+2^24 us) and the offset becomes -16.8 s
    assert st.values['clock_offset_ns'] == '0' and st.values['clock_resets'] == '1'
    assert 2e9 < stamps[0] < 2.2e9                            # the sensor time, as converted
