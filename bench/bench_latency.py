"""Latency and drops of the node graph at 1x replay (issue 6 acceptance).

Simulates a rotation sequence (20 s by default, cached in ``--work``), converts it to a bag
(EventPacket mono, 2 ms packets), starts ``packetizer_node`` and ``resonator_node`` as real
processes with ``config/shapes_rotation.yaml``, and replays the event packets itself at 1x in
real time, BEST_EFFORT depth 1000 as a camera driver publishes, recording the wall time of every
publish. A subscriber thread in this process stamps every ``~/odom`` on arrival. The latency of
a frame is (Odometry received) − (publish of the event packet that completed the frame); the
Odometry is received ~0.1 ms after it is published, so this slightly overestimates "event packet
published → Odometry published". Prints frames in vs out, drops and the latency percentiles next
to the targets (no drop, median ≤ 5 ms, p99 ≤ 20 ms).

    scripts/run.sh python bench/bench_latency.py                  # 20 s rotation, seed 11
    scripts/run.sh python bench/bench_latency.py --seconds 5 --work /tmp/lat5
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import sys
import threading
import time

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from event_camera_msgs.msg import EventPacket  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from hrn_vo_ros.core.events.frames import frames_from_events  # noqa: E402
from hrn_vo_ros.io import bags  # noqa: E402
from hrn_vo_ros.io.convert import convert  # noqa: E402
from hrn_vo_ros.io.ecd import read_events, read_sensor_size, write_sequence  # noqa: E402
from hrn_vo_ros.io.yamlconfig import load_configs  # noqa: E402
from hrn_vo_ros.nodes import graph as G  # noqa: E402,N812
from hrn_vo_ros.nodes.common import qos  # noqa: E402

CONFIG = ROOT / 'config' / 'shapes_rotation.yaml'


def prepare(work: Path, seconds: float, seed: int) -> tuple[Path, Path]:
    """The simulated sequence and its bag (re-used when present)."""
    seq, bag = work / 'sequence', work / 'bag'
    if not seq.exists():
        from hrn_vo_ros.core.sim.simulator import simulate
        t0 = time.perf_counter()
        write_sequence(seq, simulate('rotation', seconds, seed=seed))
        print(f'simulated {seconds:g} s in {time.perf_counter() - t0:.0f} s -> {seq}')
    if not bag.exists():
        convert(seq, bag)
    return seq, bag


def load_packets(bag: Path) -> tuple[list[tuple[int, bytes]], list[int]]:
    """(bag time, CDR bytes) of every event packet, and each packet's event count."""
    reader = bags.open_bag(bag)
    out, counts, ts = [], [], bags.typestore()
    try:
        for m in bags.iter_messages(reader, [G.EVENTS_TOPIC]):
            raw = bytes(m.raw)
            out.append((m.t_ns, raw))
            counts.append(len(ts.deserialize_cdr(raw, m.msgtype).events) // 8)
    finally:
        reader.close()
    return out, counts


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seconds', type=float, default=20.0)
    p.add_argument('--seed', type=int, default=11)
    p.add_argument('--work', type=Path, default=Path('/tmp/hrn_bench_latency'))
    args = p.parse_args()
    seq, bag = prepare(args.work, args.seconds, args.seed)
    width, height = read_sensor_size(seq)
    pcfg, _ = load_configs(CONFIG, packetizer={'sensor_width': width, 'sensor_height': height})
    t_frames, _ = frames_from_events(read_events(seq), pcfg)
    packets, counts = load_packets(bag)
    # frame k is complete with event (k+1)·N − 1: the packet holding it completes the frame
    cum = np.cumsum(counts)
    n = len(t_frames)
    completing = np.searchsorted(cum, (np.arange(n) + 1) * pcfg.events_per_frame, side='left')
    frame_of = {int(t): k for k, t in enumerate(t_frames)}
    print(f'{len(packets)} packets, {int(cum[-1])} events, {n} frames expected '
          f'({args.seconds:g} s, {pcfg.events_per_frame} events per frame)')

    os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
    rclpy.init()
    graph, mon = G.Graph(args.work / 'logs'), G.Monitor()
    received = np.full(n, np.nan)
    extra = 0
    try:
        params = {'sensor_width': width, 'sensor_height': height,
                  'diagnostics_period_s': 0.25}
        graph.start_module('packetizer_node', 'packetizer_node',
                           G.ros_args(CONFIG, params, {'~/events': G.EVENTS_TOPIC}))
        graph.start_module('resonator_node', 'resonator_node', G.ros_args(
            CONFIG, {'diagnostics_period_s': 0.25}, {'~/frames': G.FRAMES_TOPIC}))
        sub_node = rclpy.create_node('latency_probe')

        def on_odom(msg: Odometry) -> None:
            nonlocal extra
            now = time.perf_counter()
            k = frame_of.get(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
            if k is None:
                extra += 1
            else:
                received[k] = now
        sub_node.create_subscription(Odometry, G.ODOM_TOPIC, on_odom, qos(1000))
        pub = mon.node.create_publisher(EventPacket, G.EVENTS_TOPIC, qos(1000, reliable=False))
        mon.wait(lambda: pub.get_subscription_count() > 0
                 and mon.value('packetizer_node', 'frames_subscribers', 0) > 0
                 and mon.value('resonator_node', 'odom_subscribers', 0) > 0, 60,
                 'the graph', graph)
        ex = SingleThreadedExecutor()
        ex.add_node(sub_node)
        stop = threading.Event()

        def spin() -> None:
            while not stop.is_set():
                ex.spin_once(timeout_sec=0.05)
        spinner = threading.Thread(target=spin)
        spinner.start()
        time.sleep(1.0)
        sent = np.empty(len(packets))
        t_bag0, t_wall0 = packets[0][0], time.perf_counter() + 0.1
        for i, (t_bag, raw) in enumerate(packets):
            due = t_wall0 + (t_bag - t_bag0) * 1e-9
            while (lag := due - time.perf_counter()) > 0:
                time.sleep(min(lag, 0.002))
            sent[i] = time.perf_counter()
            pub.publish(raw)
        print(f'replayed in {time.perf_counter() - t_wall0:.2f} s (bag '
              f'{(packets[-1][0] - t_bag0) * 1e-9:.2f} s)')
        end = time.monotonic() + 10
        while np.isnan(received).any() and time.monotonic() < end:
            time.sleep(0.1)
        settle = time.monotonic() + 1.0   # let the last diagnostics arrive
        mon.wait(lambda: time.monotonic() > settle, 5, 'diagnostics')
        stop.set()
        spinner.join()
        diags = dict(mon.diags)
        cpu = {nd.name: cpu_seconds(nd.proc.pid) for nd in graph.nodes}
    finally:
        graph.stop()
        mon.close()
        rclpy.try_shutdown()
    got = ~np.isnan(received)
    lat_ms = (received[got] - sent[completing[got]]) * 1e3
    made = diags.get('packetizer_node', {}).get('frames_out', '?')
    print(f'frames expected {n}, made by the packetizer {made}, odometry out {int(got.sum())}, '
          f'dropped {n - int(got.sum())} (unmatched stamps {extra}); bad messages '
          f'packetizer {diags.get("packetizer_node", {}).get("bad_total", "?")}, '
          f'resonator {diags.get("resonator_node", {}).get("bad_total", "?")}')
    med, p99 = float(np.median(lat_ms)), float(np.percentile(lat_ms, 99))
    print(f'end-to-end latency (packet published -> odometry received): median {med:.2f} ms, '
          f'p90 {np.percentile(lat_ms, 90):.2f} ms, p99 {p99:.2f} ms, max {lat_ms.max():.2f} ms')
    rs = diags.get('resonator_node', {})
    print(f'resonator processing per frame: median {rs.get("processing_ms_median")} ms, p99 '
          f'{rs.get("processing_ms_p99")} ms (recent window); packetizer per packet: median '
          f'{diags.get("packetizer_node", {}).get("processing_ms_median")} ms')
    print('CPU time of the node processes (whole run, incl. start-up): ' + ', '.join(
        f'{k} {v:.2f} s = {v / max(n, 1) * 1e3:.2f} ms per frame' for k, v in cpu.items())
        + f'; frame period {args.seconds / max(n, 1) * 1e3:.2f} ms; load average '
        f'{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores')
    ok = n == int(got.sum()) and med <= 5.0 and p99 <= 20.0
    print(f'targets (no drop, median <= 5 ms, p99 <= 20 ms): {"met" if ok else "NOT met"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
