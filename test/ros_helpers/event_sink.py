"""A real rclpy subscriber process for the bag player tests.

Usage: ``event_sink.py TOPIC EXPECTED_PACKETS TIMEOUT_S [reliable]``. Subscribes ``TOPIC``
(EventPacket, best effort, depth 1000, like the drivers' consumers; ``reliable``: RELIABLE,
KEEP_ALL and a slow callback, to check that max-rate playback is paced) and ``/clock``, decodes
every packet, and prints one JSON line: packets, events, checksum, seq numbers missing, clock ticks
(count, first, last, monotonic). Exits 0 when all expected packets arrived, 1 on timeout.
"""

from __future__ import annotations

import json
import sys
import time

from event_camera_msgs.msg import EventPacket
import rclpy
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from hrn_vo_ros.core.events.arrays import EventChecksum
from hrn_vo_ros.io import eventpacket


def main() -> int:
    topic, expected, timeout = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
    reliable = sys.argv[4:] == ['reliable']
    rclpy.init()
    node = Node('event_sink')
    checksum = EventChecksum()
    seqs: list[int] = []
    clock: list[int] = []

    def on_packet(msg: EventPacket) -> None:
        if reliable:
            time.sleep(0.002)  # slower than the player could publish
        seqs.append(int(msg.seq))
        checksum.update(eventpacket.decode(msg.encoding, bytes(msg.events),
                                           time_base=int(msg.time_base)))

    def on_clock(msg: Clock) -> None:
        clock.append(msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)

    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE) if reliable else \
        QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
    node.create_subscription(EventPacket, topic, on_packet, qos)
    node.create_subscription(Clock, '/clock', on_clock, QoSProfile(depth=1000))
    print('ready', flush=True)  # noqa: T201 (the test reads stdout)
    deadline = time.monotonic() + timeout
    first = None
    while time.monotonic() < deadline and len(seqs) < expected:
        rclpy.spin_once(node, timeout_sec=0.1)
        if first is None and seqs:
            first = time.monotonic()
    end = time.monotonic() + 1.0  # the last /clock ticks follow the last packet
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    out = {'packets': len(seqs), 'events': checksum.count, 'checksum': checksum.hexdigest(),
           'missing': sorted(set(range(expected)) - set(seqs))[:20],
           'duration_s': None if first is None else time.monotonic() - 1.0 - first,
           'clock': {'n': len(clock), 'first': clock[0] if clock else None,
                     'last': clock[-1] if clock else None,
                     'monotonic': all(a <= b for a, b in zip(clock, clock[1:], strict=False))}}
    print(json.dumps(out), flush=True)  # noqa: T201
    node.destroy_node()
    rclpy.try_shutdown()
    return 0 if len(seqs) >= expected else 1


if __name__ == '__main__':
    sys.exit(main())
