"""packetizer_node and resonator_node as real rclpy nodes over DDS: data flow and bad input."""

from __future__ import annotations

from collections.abc import Callable, Iterator
import contextlib
from dataclasses import dataclass
import math
import time

from diagnostic_msgs.msg import DiagnosticArray
from event_camera_msgs.msg import EventPacket
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers import spin_until
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import frames_from_events, Packetizer
from hrn_vo_ros.core.events.packet_config import paper_framing, with_calibration
from hrn_vo_ros.core.events.sequence import CameraCalibration
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.eventpacket import encode_mono
from hrn_vo_ros.nodes.common import qos
from hrn_vo_ros.nodes.packetizer_node import PacketizerNode
from hrn_vo_ros.nodes.resonator_node import ResonatorNode

pytestmark = pytest.mark.ros
PER_FRAME = 500
# plain binning (no noise floor: it would hold the short test streams for its 250 ms window)
PLAIN = Parameter('noise_floor_hz', value=0.0)


def random_events(rng: np.random.Generator, n: int, t0: int = 1_000_000) -> EventArray:
    t = t0 + np.cumsum(rng.integers(1, 2000, n))
    return EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                  rng.integers(0, 2, n))


def packet(ev: EventArray, seq: int, encoding: str = 'mono') -> EventPacket:
    base, payload = encode_mono(ev)
    msg = EventPacket(height=180, width=240, seq=seq, time_base=base, encoding=encoding,
                      is_bigendian=False)
    msg.header.stamp = ros_msgs.ns_to_stamp(base)     # as hrn-vo convert: header = time_base
    msg.events = payload.tobytes()
    return msg


class Graph:
    """The two nodes plus a probe node that feeds and listens, on one executor."""

    def __init__(self, imu: bool = False) -> None:
        params = [Parameter('events_per_frame', value=PER_FRAME), PLAIN,
                  Parameter('events_reliable', value=True), Parameter('diagnostics_period_s',
                                                                      value=0.2)]
        remap = ['--ros-args', '-r', '~/frames:=/frames']
        self.packetizer = PacketizerNode(parameter_overrides=params, cli_args=remap)
        self.resonator = ResonatorNode(cli_args=remap, parameter_overrides=[
            Parameter('diagnostics_period_s', value=0.2), Parameter('imu.enabled', value=imu),
            Parameter('focal_px', value=80.0), Parameter('imu_timeout_s', value=0.3)])
        self.probe = Node('probe')
        self.ev_pub = self.probe.create_publisher(EventPacket, '/packetizer_node/events',
                                                  qos(1000))
        self.frame_pub = self.probe.create_publisher(Image, '/frames', qos(100))
        self.imu_pub = self.probe.create_publisher(Imu, '/resonator_node/imu', qos(100))
        self.frames: list[Image] = []
        self.readouts: list[JointState] = []
        self.odoms: list[Odometry] = []
        self.diags: dict[str, dict[str, str]] = {}
        self.probe.create_subscription(Image, '/frames', self.frames.append,
                                       qos(1000))
        self.probe.create_subscription(JointState, '/resonator_node/readout',
                                       self.readouts.append, qos(1000))
        self.probe.create_subscription(Odometry, '/resonator_node/odom', self.odoms.append,
                                       qos(1000))
        self.probe.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 100)
        self.ex = SingleThreadedExecutor()
        for n in (self.packetizer, self.resonator, self.probe):
            self.ex.add_node(n)
        self.wait(lambda: self.ev_pub.get_subscription_count() > 0
                  and self.frame_pub.get_subscription_count() > 0)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        self.diags[msg.status[0].name.split(':')[0]] = ros_msgs.diagnostic_values(msg)

    def wait(self, cond: Callable[[], bool], timeout: float = 10.0) -> bool:
        return spin_until(self.ex, cond, timeout)

    def close(self) -> None:
        for n in (self.packetizer, self.resonator, self.probe):
            n.destroy_node()


@pytest.fixture
def graph() -> Iterator[Graph]:
    rclpy.init()
    g = Graph()
    try:
        yield g
    finally:
        g.close()
        rclpy.try_shutdown()


def test_packets_become_frames_and_odometry(graph: Graph, rng: np.random.Generator) -> None:
    ev = random_events(rng, 10 * PER_FRAME + 123)
    cuts = [0, 7, 900, 901, 2600, 5000, len(ev)]      # splits frames, spans several frames
    for i, (a, b) in enumerate(zip(cuts[:-1], cuts[1:], strict=True)):
        graph.ev_pub.publish(packet(ev[a:b], seq=i))
    assert graph.wait(lambda: len(graph.odoms) >= 10)
    t_ref, images = frames_from_events(ev, paper_framing(events_per_frame=PER_FRAME))
    got = [ros_msgs.image_to_frame(m) for m in graph.frames]
    assert [t for t, _ in got] == t_ref.tolist()
    assert all(np.array_equal(img, ref) for (_, img), ref in zip(got, images, strict=True))
    assert graph.frames[0].encoding == 'mono8' and max(graph.frames[0].data) == 255
    assert graph.frames[0].header.frame_id == 'event_camera_optical_frame'
    assert [ros_msgs.stamp_to_ns(m.header.stamp) for m in graph.odoms] == t_ref.tolist()
    assert list(graph.readouts[-1].name)[:3] == ['h', 'v', 'r']   # then quality, state
    odom = graph.odoms[-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')
    assert all(math.isfinite(c) for c in odom.pose.covariance) and odom.pose.covariance[0] > 0
    assert graph.wait(lambda: graph.diags.get('resonator_node', {}).get('estimates_out') == '10')


def test_malformed_packets_are_counted_and_survived(graph: Graph,
                                                    rng: np.random.Generator) -> None:
    ev = random_events(rng, 4 * PER_FRAME)
    graph.ev_pub.publish(packet(ev[:PER_FRAME], 0))
    graph.ev_pub.publish(packet(ev[PER_FRAME:2 * PER_FRAME], 1, encoding='libcaer_cmp'))
    graph.ev_pub.publish(packet(EventArray.empty(), 2))
    bad_xy = EventArray.from_arrays(ev.t[:10] + ev.t[-1], np.full(10, 300), ev.y[:10],
                                    ev.p[:10])
    graph.ev_pub.publish(packet(bad_xy, 3))
    graph.ev_pub.publish(packet(ev[:PER_FRAME], 4))                 # back in time
    graph.ev_pub.publish(packet(ev[2 * PER_FRAME:], 7))              # seq gap of 2, good data
    assert graph.wait(lambda: graph.diags.get('packetizer_node', {}).get('frames_out') == '3')
    d = graph.diags['packetizer_node']
    assert (d['bad_decode'], d['bad_empty'], d['bad_out_of_sensor'], d['bad_time_backwards'],
            d['seq_gaps']) == ('1', '1', '1', '1', '2')
    assert len(graph.frames) == 3


def test_malformed_frames_are_counted_and_survived(graph: Graph) -> None:
    good = ros_msgs.frame_to_image(np.eye(72, 96, dtype=np.uint8), 2_000_000, 'cam')
    rgb = ros_msgs.frame_to_image(np.eye(72, 96, dtype=np.uint8), 3_000_000, 'cam')
    rgb.encoding = 'rgb8'
    small = ros_msgs.frame_to_image(np.eye(10, 10, dtype=np.uint8), 4_000_000, 'cam')
    old = ros_msgs.frame_to_image(np.eye(72, 96, dtype=np.uint8), 1_000_000, 'cam')
    later = ros_msgs.frame_to_image(np.eye(72, 96, dtype=np.uint8), 5_000_000, 'cam')
    for m in (good, rgb, small, old, later):
        graph.frame_pub.publish(m)
    assert graph.wait(lambda: graph.diags.get('resonator_node', {}).get('bad_total') == '3'
                      and len(graph.odoms) == 2)
    d = graph.diags['resonator_node']
    assert (d['bad_decode'], d['bad_size'], d['bad_time_backwards']) == ('1', '1', '1')
    assert (d['relocalisations'], d['gaps']) == ('0', '0')     # the real tracker's counts


def test_imu_frames_wait_for_gyro_and_nan_imu_is_rejected() -> None:
    rclpy.init()
    g = Graph(imu=True)
    try:
        def imu(t_ns: int, wz: float) -> Imu:
            m = Imu()
            m.header.stamp = ros_msgs.ns_to_stamp(t_ns)
            m.angular_velocity.z = wz
            return m
        g.wait(lambda: g.imu_pub.get_subscription_count() > 0)
        for k in range(1, 4):
            g.frame_pub.publish(ros_msgs.frame_to_image(np.eye(72, 96, dtype=np.uint8),
                                                        k * 10_000_000, 'cam'))
        g.imu_pub.publish(imu(0, 0.0))
        g.imu_pub.publish(imu(15_000_000, math.nan))
        g.imu_pub.publish(imu(25_000_000, 1.0))
        assert g.wait(lambda: len(g.odoms) == 2)          # the third still waits for IMU
        g.ex.spin_once(timeout_sec=0.1)
        assert len(g.odoms) == 2
        assert g.wait(lambda: len(g.odoms) == 3, timeout=3.0)   # imu_timeout_s flushes it
        assert g.wait(lambda: g.diags.get('resonator_node', {}).get('bad_imu') == '1')
    finally:
        g.close()
        rclpy.try_shutdown()


def test_tf_and_images_when_enabled() -> None:
    from tf2_msgs.msg import TFMessage

    rclpy.init()
    try:
        node = ResonatorNode(parameter_overrides=[
            Parameter('publish_tf', value=True),
            Parameter('odometry.child_frame', value='camera'),
            Parameter('camera_frame_id', value='cam_optical')])
        probe = Node('tf_probe')
        got: dict[str, list] = {'tf': [], 'map': [], 'img': []}
        probe.create_subscription(TFMessage, '/tf', got['tf'].append, 100)
        probe.create_subscription(Image, '/resonator_node/map_image', got['map'].append, 10)
        probe.create_subscription(Image, '/resonator_node/readout_image', got['img'].append, 10)
        pub = probe.create_publisher(Image, '/resonator_node/frames', qos(10))
        ex = SingleThreadedExecutor()
        ex.add_node(node)
        ex.add_node(probe)
        end = time.monotonic() + 10
        while time.monotonic() < end and not pub.get_subscription_count():
            ex.spin_once(timeout_sec=0.05)
        pub.publish(ros_msgs.frame_to_image(np.eye(72, 96, dtype=np.uint8), 7, 'c'))
        while time.monotonic() < end and not (got['tf'] and got['map'] and got['img']):
            ex.spin_once(timeout_sec=0.05)
        tf = got['tf'][0].transforms[0]
        assert (tf.header.frame_id, tf.child_frame_id) == ('odom', 'cam_optical')
        # the readout image spans the canvas: 4/3 of the 96x72 frame
        assert got['map'][0].encoding == 'mono8' and got['img'][0].width == 128
        node.destroy_node()
        probe.destroy_node()
    finally:
        rclpy.try_shutdown()


def camera_info(calib: CameraCalibration | None) -> CameraInfo:
    m = CameraInfo(width=240, height=180, distortion_model='plumb_bob')
    if calib is not None:
        m.k = [calib.fx, 0.0, calib.cx, 0.0, calib.fy, calib.cy, 0.0, 0.0, 1.0]
        m.d = list(calib.dist)
    return m


@dataclass
class Lone:
    """A packetizer node alone with a probe node: events in, frames and diagnostics out."""

    ex: SingleThreadedExecutor
    probe: Node
    ev_pub: Publisher
    frames: list[Image]
    diags: list[dict[str, str]]

    def wait(self, cond: Callable[[], bool], timeout: float = 10.0) -> bool:
        return spin_until(self.ex, cond, timeout)


@contextlib.contextmanager
def lone_packetizer(*params: Parameter) -> Iterator[Lone]:
    """rclpy up, the packetizer node (PER_FRAME events per frame, reliable events,
    diagnostics every 0.2 s, plus ``params``) and a probe; everything torn down after."""
    rclpy.init()
    node = PacketizerNode(parameter_overrides=[
        Parameter('events_per_frame', value=PER_FRAME), Parameter('events_reliable', value=True),
        Parameter('diagnostics_period_s', value=0.2), PLAIN, *params])
    probe = Node('probe')
    try:
        lone = Lone(SingleThreadedExecutor(), probe,
                    probe.create_publisher(EventPacket, '/packetizer_node/events', qos(1000)),
                    [], [])
        probe.create_subscription(Image, '/packetizer_node/frames', lone.frames.append,
                                  qos(1000))
        probe.create_subscription(
            DiagnosticArray, '/diagnostics',
            lambda m: lone.diags.append(ros_msgs.diagnostic_values(m)), 100)
        lone.ex.add_node(node)
        lone.ex.add_node(probe)
        assert lone.wait(lambda: lone.ev_pub.get_subscription_count() > 0)
        yield lone
    finally:
        node.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown()


def test_rectifying_packetizer_holds_events_until_camera_info(rng: np.random.Generator) -> None:
    """Events before the (latched) camera_info are held, not lost; bad camera_info is rejected."""
    calib = CameraCalibration(240, 180, 199.1, 198.8, 121.3, 89.6, (-0.12, 0.03, 0.0, 0.0, 0.0))
    with lone_packetizer(Parameter('rectify', value='equidistant')) as lone:
        ev_pub, frames, diags, wait = lone.ev_pub, lone.frames, lone.diags, lone.wait
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        info_pub = lone.probe.create_publisher(CameraInfo, '/packetizer_node/camera_info',
                                               latched)
        ev = random_events(rng, 6 * PER_FRAME + 50)
        ev_pub.publish(packet(ev[:2500], 0))
        ev_pub.publish(packet(ev[2500:], 1))
        assert wait(lambda: any(d.get('events_held') == str(len(ev)) for d in diags))
        assert not frames and diags[-1]['waiting_for_camera_info'] == 'True'
        info_pub.publish(camera_info(None))                       # uncalibrated: rejected
        assert wait(lambda: any(d.get('bad_camera_info') == '1' for d in diags))
        assert not frames
        info_pub.publish(camera_info(calib))                      # latched, as bags replay it
        assert wait(lambda: len(frames) == 6)
        cfg = with_calibration(paper_framing(events_per_frame=PER_FRAME,
                                             rectify='equidistant'), calib)
        t_ref, images = frames_from_events(ev, cfg)
        got = [ros_msgs.image_to_frame(m) for m in frames]
        assert [t for t, _ in got] == t_ref.tolist()
        assert all(np.array_equal(img, ref) for (_, img), ref in zip(got, images, strict=True))
        # the held events were rectified: they differ from plain binning
        _, plain = frames_from_events(ev, paper_framing(events_per_frame=PER_FRAME))
        assert not np.array_equal(plain, images)
        assert wait(lambda: diags[-1].get('waiting_for_camera_info') == 'False'
                    and diags[-1].get('events_held') == '0')


def test_denoising_packetizer_drops_lone_events_and_counts_them(
        rng: np.random.Generator) -> None:
    """denoise_ms as a ROS parameter: the node's frames are those of the offline packetizer
    with the filter, on packets that split bins, and /diagnostics counts the drops."""
    with lone_packetizer(Parameter('denoise_ms', value=0.02)) as lone:
        ev_pub, frames, diags = lone.ev_pub, lone.frames, lone.diags
        # pairs of neighbouring pixels firing together (kept) among lone events (dropped)
        n = 3000
        # 20 us apart on average, bins of 20 us (a short span: the stream's clock takes long
        # packets published at once for a header jump)
        t = 1_000_000 + np.cumsum(rng.integers(1, 4000, n)) * 10
        x, y = rng.integers(1, 239, n), rng.integers(0, 180, n)
        pair = rng.random(n) < 0.5
        t2 = np.concatenate([t, t[pair] + 1])
        x2 = np.concatenate([x, x[pair] + 1])
        y2 = np.concatenate([y, y[pair]])
        order = np.argsort(t2, kind='stable')
        ev = EventArray.from_arrays(t2[order], x2[order], y2[order],
                                    np.ones(len(t2), np.uint8))
        cuts = [0, 1000, 1001, 2500, len(ev)]
        for i, (a, b) in enumerate(zip(cuts[:-1], cuts[1:], strict=True)):
            ev_pub.publish(packet(ev[a:b], seq=i))
        offline = Packetizer(paper_framing(events_per_frame=PER_FRAME, denoise_ms=0.02))
        ref = []
        for a, b in zip(cuts[:-1], cuts[1:], strict=True):
            ref += offline.push(ev[a:b])
        assert offline.denoised > 0.45 * n and len(ref) >= 3       # the ~n/2 lone events
        assert lone.wait(lambda: len(frames) >= len(ref))
        got = [ros_msgs.image_to_frame(m) for m in frames]
        assert [tt for tt, _ in got] == [f.t_ns for f in ref]
        assert all(np.array_equal(img, f.image) for (_, img), f in zip(got, ref, strict=True))
        assert lone.wait(lambda: any(d.get('events_denoised') == str(offline.denoised)
                                     for d in diags))


def test_rate_capped_packetizer_keeps_an_even_share_and_counts_the_rest(
        rng: np.random.Generator) -> None:
    """max_frame_hz as a ROS parameter: 1 M events/s for 60 ms, a cap of 100 frames/s of 500
    events (500 per 10 ms window): after the first window one event in 20 is kept. The node's
    frames are the offline packetizer's, on packets that split windows, and /diagnostics counts
    the events left out."""
    with lone_packetizer(Parameter('max_frame_hz', value=100.0)) as lone:
        n = 60_000
        t = 1_000_000 + np.arange(n, dtype=np.int64) * 1000
        ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                    np.ones(n, np.uint8))
        cuts = [0, 7000, 7001, 25_000, 41_234, n]
        for i, (a, b) in enumerate(zip(cuts[:-1], cuts[1:], strict=True)):
            lone.ev_pub.publish(packet(ev[a:b], seq=i))
        offline = Packetizer(paper_framing(events_per_frame=PER_FRAME, max_frame_hz=100.0))
        ref = offline.push(ev)
        # windows of 10 ms from t = 0: the first (1-10 ms, 9000 events) is kept whole, the next
        # (10 000 after 9000) keeps floor(10 000 x 500 / 9000) = 555, the four after it 500
        # each, the last (1000 events, 60-61 ms) at share 1/20: 50; 11 605 kept
        assert offline.capped == n - 9000 - 555 - 4 * 500 - 50 and len(ref) == 23
        assert lone.wait(lambda: len(lone.frames) >= len(ref))
        got = [ros_msgs.image_to_frame(m) for m in lone.frames]
        assert [tt for tt, _ in got] == [f.t_ns for f in ref]
        assert all(np.array_equal(img, f.image) for (_, img), f in zip(got, ref, strict=True))
        assert lone.wait(lambda: any(d.get('events_capped') == str(offline.capped)
                                     and d.get('rate_cap_share') == '0.050'
                                     for d in lone.diags))


def test_a_slow_stream_gets_refilled_frames_and_counts_them(rng: np.random.Generator) -> None:
    """max_frame_ms 50 and refill as ROS parameters, a stream of one event per ms: packets
    close by time after 50 events and are binned with the 450 before them. The node's frames
    are the offline packetizer's, and /diagnostics counts the frames closed by time."""
    with lone_packetizer(Parameter('max_frame_ms', value=50.0),
                         Parameter('min_frame_events', value=20),
                         Parameter('refill', value=True)) as lone:
        n = 1500
        t = 1_000_000 + np.arange(n, dtype=np.int64) * 1_000_000
        ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                    np.ones(n, np.uint8))
        cuts = [0, 333, 334, 1000, n]
        for i, (a, b) in enumerate(zip(cuts[:-1], cuts[1:], strict=True)):
            lone.ev_pub.publish(packet(ev[a:b], seq=i))
        offline = Packetizer(paper_framing(events_per_frame=PER_FRAME, max_frame_ms=50.0,
                                           min_frame_events=20, refill=True))
        ref = offline.push(ev)
        # 29 packets of 50 events (the 30th still open); from the 10th on each frame holds 500
        assert len(ref) == offline.by_time == 29
        assert [f.n_events for f in ref] == [50 * (i + 1) for i in range(10)] + [500] * 19
        assert lone.wait(lambda: len(lone.frames) >= len(ref))
        got = [ros_msgs.image_to_frame(m) for m in lone.frames]
        assert [tt for tt, _ in got] == [f.t_ns for f in ref]
        assert all(np.array_equal(img, f.image) for (_, img), f in zip(got, ref, strict=True))
        assert lone.wait(lambda: any(d.get('frames_by_time') == '29' for d in lone.diags))


def test_a_shallow_frame_queue_drops_the_oldest_and_counts_them() -> None:
    """frames_depth 2 and a resonator that does not take frames for a while (here: not spun):
    only the newest two of 30 are processed, the 28 before them are counted as dropped (the
    publisher's sequence numbers) and the diagnostics WARN that the resonator falls behind."""
    rclpy.init()
    node = ResonatorNode(parameter_overrides=[
        Parameter('frames_depth', value=2), Parameter('diagnostics_period_s', value=0.1),
        Parameter('map_image_rate_hz', value=0.0)])
    probe = Node('queue_probe')
    odoms: list[Odometry] = []
    diags: list[DiagnosticArray] = []
    pub = probe.create_publisher(Image, '/resonator_node/frames', qos(100))
    probe.create_subscription(Odometry, '/resonator_node/odom', odoms.append, qos(100))
    probe.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 100)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    ex.add_node(probe)
    try:
        assert spin_until(ex, lambda: pub.get_subscription_count() > 0, 10.0)
        frame = np.eye(72, 96, dtype=np.uint8)
        pub.publish(ros_msgs.frame_to_image(frame, 1_000_000_000, 'cam'))
        assert spin_until(ex, lambda: len(odoms) == 1, 10.0)
        for k in range(1, 31):               # published while the node takes nothing
            pub.publish(ros_msgs.frame_to_image(frame, 1_000_000_000 + k * 1_000_000, 'cam'))
        time.sleep(1.0)                      # all delivered into the 2-deep queue
        assert spin_until(ex, lambda: len(odoms) == 3, 10.0)
        assert [ros_msgs.stamp_to_ns(m.header.stamp) for m in odoms[1:]] == [
            1_029_000_000, 1_030_000_000]    # the newest two
        def last() -> dict[str, str]:
            return ros_msgs.diagnostic_values(diags[-1]) if diags else {}
        assert spin_until(ex, lambda: last().get('frames_in') == '3', 10.0)
        status = diags[-1].status[0]
        assert last()['seq_gaps'] == '28' and status.level == b'\x01'
        assert status.message.startswith('28 frames dropped before the resonator')
    finally:
        node.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown()
