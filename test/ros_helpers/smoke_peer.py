"""A real rclpy process for the smoke test: ``talker`` publishes, ``listener`` checks content.

The listener prints one JSON line with what it received and exits 0, or exits 1 after the
timeout if a message is missing or differs.
"""

from __future__ import annotations

import json
import sys
import time

from event_camera_msgs.msg import EventPacket
from nav_msgs.msg import Odometry
import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy

EVENTS_X = np.array([1, 239, 17, 100], np.uint64)
EVENTS_Y = np.array([2, 179, 90, 0], np.uint64)
EVENTS_P = np.array([1, 0, 1, 1], np.uint64)
EVENTS_DT = np.array([0, 10, 1_000_000, 4_000_000_000], np.uint64)
TIME_BASE = 1_700_000_000_123_456_789


def make_packet() -> EventPacket:
    words = (EVENTS_P << 63) | (EVENTS_Y << 48) | (EVENTS_X << 32) | EVENTS_DT
    msg = EventPacket()
    msg.header.frame_id = 'event_camera_optical_frame'
    msg.height, msg.width, msg.seq, msg.time_base = 180, 240, 7, TIME_BASE
    msg.encoding, msg.is_bigendian = 'mono', False
    msg.events = words.astype('<u8').tobytes()
    return msg


def make_odom() -> Odometry:
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = 'odom', 'base_link'
    msg.pose.pose.position.x, msg.pose.pose.position.y = 1.25, -0.5
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = 0.6, 0.8
    msg.pose.covariance[0] = 0.01
    return msg


def talker(seconds: float) -> int:
    node = Node('smoke_talker')
    best_effort = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
    pub_ev = node.create_publisher(EventPacket, 'smoke/events', best_effort)
    pub_odom = node.create_publisher(Odometry, 'smoke/odom', 10)
    end = time.monotonic() + seconds
    while time.monotonic() < end and rclpy.ok():
        pub_ev.publish(make_packet())
        pub_odom.publish(make_odom())
        rclpy.spin_once(node, timeout_sec=0.05)
    node.destroy_node()
    return 0


def listener(seconds: float) -> int:
    node = Node('smoke_listener')
    got: dict[str, object] = {}

    def on_events(msg: EventPacket) -> None:
        words = np.frombuffer(bytes(msg.events), '<u8')
        got['events'] = {
            'x': ((words >> 32) & 0xFFFF).tolist(), 'y': ((words >> 48) & 0x7FFF).tolist(),
            'p': (words >> 63).tolist(), 'dt': (words & 0xFFFFFFFF).tolist(),
            'time_base': msg.time_base, 'encoding': msg.encoding, 'seq': msg.seq,
            'width': msg.width, 'height': msg.height}

    def on_odom(msg: Odometry) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        got['odom'] = {'frame': msg.header.frame_id, 'child': msg.child_frame_id,
                       'xyz': [p.x, p.y, p.z], 'q': [q.x, q.y, q.z, q.w],
                       'cov0': msg.pose.covariance[0]}

    node.create_subscription(EventPacket, 'smoke/events', on_events, qos_profile_sensor_data)
    node.create_subscription(Odometry, 'smoke/odom', on_odom, 10)
    end = time.monotonic() + seconds
    while time.monotonic() < end and len(got) < 2:
        rclpy.spin_once(node, timeout_sec=0.1)
    node.destroy_node()
    print(json.dumps(got), flush=True)  # noqa: T201
    expected_events = {
        'x': EVENTS_X.tolist(), 'y': EVENTS_Y.tolist(), 'p': EVENTS_P.tolist(),
        'dt': EVENTS_DT.tolist(), 'time_base': TIME_BASE, 'encoding': 'mono', 'seq': 7,
        'width': 240, 'height': 180}
    ok = got.get('events') == expected_events and got.get('odom') == {
        'frame': 'odom', 'child': 'base_link', 'xyz': [1.25, -0.5, 0.0],
        'q': [0.0, 0.0, 0.6, 0.8], 'cov0': 0.01}
    return 0 if ok else 1


def main() -> int:
    role, seconds = sys.argv[1], float(sys.argv[2])
    rclpy.init()
    try:
        return talker(seconds) if role == 'talker' else listener(seconds)
    finally:
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
