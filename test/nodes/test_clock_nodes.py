"""A driver-like stream through the two nodes over DDS: stamps in the header clock, resets."""

from __future__ import annotations

import time

import numpy as np
import pytest
import rclpy
from test_nodes import Graph, packet

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.io import ros_msgs

pytestmark = pytest.mark.ros
MS = 1_000_000


def test_driver_stream_is_stamped_in_the_header_clock_and_survives_a_restart(
        rng: np.random.Generator) -> None:
    rclpy.init()
    g = Graph()
    try:
        sent: list[tuple[int, int, int]] = []      # (header start, header end, wall ns)
        t_restart_wall = 0.0

        def send(k: int, sensor0: int, header0: int, n: int = 250) -> None:
            t = sensor0 + np.sort(rng.integers(0, 5 * MS, n))
            ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                        rng.integers(0, 2, n))
            msg = packet(ev, seq=k)
            msg.header.stamp = ros_msgs.ns_to_stamp(header0 + int(t[0]) - sensor0)
            sent.append((header0 + int(t[0]) - sensor0, header0 + int(t[-1]) - sensor0, 0))
            g.ev_pub.publish(msg)

        h0 = time.time_ns()
        for k in range(40):                          # sensor clock near 0 (camera start)
            send(k, 1000 + k * 5 * MS, h0 + k * 5 * MS)
        assert g.wait(lambda: len(g.odoms) >= 15)
        h_bad = max(time.time_ns(), h0 + 40 * 5 * MS)     # header time goes on
        send(40, 10_000 * 10**9, h_bad)             # one far-future packet
        before = len(g.odoms)
        h1 = h_bad + 5 * MS
        t_restart_wall = time.monotonic()
        for k in range(40):                          # driver restart: sensor clock from 0
            send(41 + k, 500 + k * 5 * MS, h1 + k * 5 * MS)
        assert g.wait(lambda: any(ros_msgs.stamp_to_ns(o.header.stamp) >= h1
                                  for o in g.odoms[before:]), timeout=1.0), \
            'no output within 1 s of the restart'
        assert time.monotonic() - t_restart_wall < 1.0 + 0.1
        assert g.wait(lambda: len(g.odoms) >= before + 15)
        spans = [(a, b) for a, b, _ in sent]
        for msgs in (g.frames, g.odoms):
            for m in msgs:
                s = ros_msgs.stamp_to_ns(m.header.stamp)
                dist = min(max(a - s, s - b, 0) for a, b in spans)
                assert dist <= 5 * MS, f'stamp {s} is {dist / 1e6:.1f} ms off the header clock'
        stamps = [ros_msgs.stamp_to_ns(o.header.stamp) for o in g.odoms]
        assert stamps == sorted(stamps) and stamps[0] > 10**18  # ROS time, not 1970
        assert g.wait(lambda: int(g.diags.get('packetizer_node', {}).get('clock_resets', 0))
                      >= 2)
        assert g.diags['packetizer_node'].get('bad_time_backwards') is None
    finally:
        g.close()
        rclpy.try_shutdown()
