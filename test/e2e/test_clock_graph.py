"""A driver-like stream through the node processes over DDS: stamps in the header clock, resets.

packetizer_node and resonator_node run as their own processes (as ``cli/graph.py`` starts
them); a probe node here publishes packets as a live driver does: header stamps near the wall
clock, sensor time near 0 (the camera's own counter), one far-future packet, then a driver
restart (sensor time from 0 again while the header clock goes on).
"""

from __future__ import annotations

from pathlib import Path
import time

from event_camera_msgs.msg import EventPacket
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.node import Node
from sensor_msgs.msg import Image
from test_faults import NODE_ARGS, Probe

from hrn_vo_ros.cli.graph import FRAMES_TOPIC, Graph, graph_ros_args, ODOM_TOPIC
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.eventpacket import encode_mono
from hrn_vo_ros.nodes.common import qos

pytestmark = pytest.mark.ros
MS = 1_000_000


def test_driver_stream_is_stamped_in_the_header_clock_and_survives_a_restart(
        tmp_path: Path, rng: np.random.Generator) -> None:
    rclpy.init()
    graph = Graph(tmp_path / 'logs')
    probe = Probe(Node('clock_probe'))          # publisher, diagnostics and wait of the faults
    frames: list[Image] = []
    odoms: list[Odometry] = []
    probe.node.create_subscription(Image, FRAMES_TOPIC, frames.append, qos(10000))
    probe.node.create_subscription(Odometry, ODOM_TOPIC, odoms.append, qos(10000))
    pub, diags, wait = probe.pub, probe.diags, probe.wait

    sent: list[tuple[int, int]] = []      # header-clock span of each packet

    def send(k: int, sensor0: int, header0: int, n: int = 250) -> None:
        t = sensor0 + np.sort(rng.integers(0, 5 * MS, n))
        ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                    rng.integers(0, 2, n))
        base, payload = encode_mono(ev)
        msg = EventPacket(width=240, height=180, seq=k, encoding='mono', time_base=base,
                          is_bigendian=False)
        msg.header.stamp = ros_msgs.ns_to_stamp(header0 + int(t[0]) - sensor0)
        msg.events = payload.tobytes()
        sent.append((header0 + int(t[0]) - sensor0, header0 + int(t[-1]) - sensor0))
        pub.publish(msg)  # type: ignore[attr-defined]

    try:
        args = graph_ros_args(None, imu=False, overrides={})
        for name in ('resonator_node', 'packetizer_node'):
            graph.start_module(name, name, args[name] + NODE_ARGS)
        assert wait(lambda: pub.get_subscription_count() > 0  # type: ignore[attr-defined]
                    and probe.node.count_publishers(ODOM_TOPIC) > 0
                    and probe.value('packetizer_node', 'frames_subscribers') >= 2, 60.0), diags
        # Warm up (discovery runs both ways) until an odometry message arrives; those packets
        # continue the same clocks, so they are part of the checked stream.
        h0 = time.time_ns()
        k = 0
        while not odoms and k < 400:
            for _ in range(5):
                send(k, 1000 + k * 5 * MS, h0 + k * 5 * MS)
                k += 1
            wait(lambda: bool(odoms), 1.0)
        assert odoms, ('no odometry within the warm-up', diags)
        for _ in range(40):                          # sensor clock near 0 (camera start)
            send(k, 1000 + k * 5 * MS, h0 + k * 5 * MS)
            k += 1
        n_before = len(odoms)
        assert wait(lambda: len(odoms) >= n_before + 15)
        h_bad = max(time.time_ns(), h0 + k * 5 * MS)     # header time goes on
        send(k, 10_000 * 10**9, h_bad)               # one far-future packet
        k += 1
        before = len(odoms)
        h1 = h_bad + 5 * MS
        t_restart_wall = time.monotonic()
        for j in range(40):                          # driver restart: sensor clock from 0
            send(k + j, 500 + j * 5 * MS, h1 + j * 5 * MS)
        assert wait(lambda: any(ros_msgs.stamp_to_ns(o.header.stamp) >= h1
                                for o in odoms[before:]), timeout=1.0), \
            'no output within 1 s of the restart'
        assert time.monotonic() - t_restart_wall < 1.0 + 0.1
        assert wait(lambda: len(odoms) >= before + 15)
        for msgs in (frames, odoms):
            for m in msgs:
                s = ros_msgs.stamp_to_ns(m.header.stamp)
                dist = min(max(a - s, s - b, 0) for a, b in sent)
                assert dist <= 5 * MS, f'stamp {s} is {dist / 1e6:.1f} ms off the header clock'
        stamps = [ros_msgs.stamp_to_ns(o.header.stamp) for o in odoms]
        assert stamps == sorted(stamps) and stamps[0] > 10**18  # ROS time, not 1970
        assert wait(lambda: probe.value('packetizer_node', 'clock_resets') >= 2)
        assert diags['packetizer_node'].get('bad_time_backwards') is None
        graph.check_alive()
    finally:
        codes = graph.stop(timeout=15.0)
        probe.node.destroy_node()
        rclpy.try_shutdown()
    assert all(c == 0 for c in codes.values()), (codes, graph.failed_logs(codes))
