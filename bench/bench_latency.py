"""Latency and drops of the node graph at 1x replay (latency acceptance figures).

Simulates a rotation sequence (20 s by default, cached in ``--work``; ``--dataset`` takes an
Event Camera Dataset folder instead), converts it to a bag (EventPacket mono, 2 ms packets),
starts ``packetizer_node`` and ``resonator_node`` as real processes with
``config/shapes_rotation.yaml`` and the parameters ``hrn-vo run`` derives from the dataset
(sensor and frame size, focal lengths; the calibration of ``calib.txt`` as ``calib.*``
parameters, which the config's ``rectify: equidistant`` needs), and replays the event packets
itself at 1x in real time, BEST_EFFORT depth 1000 as a camera driver publishes, recording the
wall time of every publish. A subscriber thread in this process stamps every ``~/odom`` on
arrival. The latency of a frame is (Odometry received) − (publish of the event packet that
completed the frame); the Odometry is received ~0.1 ms after it is published, so this slightly
overestimates "event packet published → Odometry published". Prints frames in vs out, drops and
the latency percentiles next to the targets (no drop, median ≤ 5 ms, p99 ≤ 20 ms).

    scripts/run.sh python bench/bench_latency.py                  # 20 s rotation, seed 11
    scripts/run.sh python bench/bench_latency.py --seconds 5 --work /tmp/lat5
    scripts/run.sh python bench/bench_latency.py --smoke --work /tmp/lat1   # only that it runs
    scripts/run.sh python bench/bench_latency.py --dataset SEQ --config config/live.yaml
    scripts/run.sh python bench/bench_latency.py --dataset SEQ --config config/live.yaml \
        --rset frames_depth=10                    # a shallow frame queue: bounded latency

``--config`` gives both nodes another params file (``config/live.yaml``: any sensor size, frames
of at most 96x72). A frame is completed by the packet holding its last binned event, so the
event-rate cap (``max_frame_hz``) is followed; denoising and rectification that drop events are
not (the shipped configs have neither, or keep every event).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import os
from pathlib import Path
import sys
import threading
import time
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from event_camera_msgs.msg import EventPacket  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from hrn_vo_ros.cli import graph as G  # noqa: E402,N812
from hrn_vo_ros.cli.run import parse_overrides  # noqa: E402
from hrn_vo_ros.core.events.frames import frames_from_events, rate_cap  # noqa: E402
from hrn_vo_ros.core.events.packet_config import with_calibration  # noqa: E402
from hrn_vo_ros.io import bags  # noqa: E402
from hrn_vo_ros.io.convert import convert  # noqa: E402
from hrn_vo_ros.io.ecd import read_calib, read_events, write_sequence  # noqa: E402
from hrn_vo_ros.io.yamlconfig import dataset_configs  # noqa: E402
from hrn_vo_ros.nodes.common import qos  # noqa: E402

CONFIG = ROOT / 'config' / 'shapes_rotation.yaml'
SMOKE_SECONDS = 1.0


@dataclass
class Plan:
    """What the replay sends and expects: packets, frames, node parameters."""

    packets: list[tuple[int, bytes]]
    t_frames: np.ndarray          # stamps of the frames the packetizer will make
    completing: np.ndarray        # index of the packet that completes each frame
    packetizer: dict[str, object]
    resonator: dict[str, object]

    @property
    def n(self) -> int:
        return len(self.t_frames)


@dataclass
class Outcome:
    """What came back: arrival time per frame, unmatched stamps, diagnostics, CPU times."""

    sent: np.ndarray
    received: np.ndarray
    extra: int
    diags: dict[str, dict[str, Any]]
    cpu: dict[str, float]


def prepare(work: Path, seconds: float, seed: int, dataset: Path | None) -> tuple[Path, Path]:
    """The sequence (simulated unless ``dataset``) and its bag, re-used when present."""
    name = dataset.name if dataset is not None else f'rotation_{seconds:g}s_seed{seed}'
    seq, bag = dataset or work / name, work / f'{name}_bag'
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


def plan(seq: Path, bag: Path, config: Path) -> Plan:
    """Packets, expected frames and node parameters, derived from the dataset as in ``run``."""
    pk_over, rs_over = G.dataset_overrides(seq, config, imu=False)
    pcfg = dataset_configs(config, seq, resonator={'imu.enabled': False}).packetizer
    if pcfg.rectify != 'none':      # calib.txt, as hrn-vo run; the node gets it as parameters
        pcfg = with_calibration(pcfg, read_calib(seq))
        c = pcfg.calib
        pk_over = {**pk_over, 'calib.fx': c.fx, 'calib.fy': c.fy, 'calib.cx': c.cx,
                   'calib.cy': c.cy, 'calib.dist': [float(d) for d in c.dist]}
    events = read_events(seq)
    t_frames, _ = frames_from_events(events, pcfg)
    packets, counts = load_packets(bag)
    # frame k is complete with the (k+1)·N-th binned event: the packet holding it completes
    # the frame (the rate cap's kept events; denoising and rectification keep them all here)
    cap = rate_cap(pcfg)
    binned = (np.arange(len(events)) if cap is None
              else np.flatnonzero(cap.mask(events.t)))
    cum = np.cumsum(counts)
    n = len(t_frames)
    last = binned[(np.arange(n) + 1) * pcfg.events_per_frame - 1]
    completing = np.searchsorted(cum, last + 1, side='left')
    print(f'{len(packets)} packets, {int(cum[-1])} events ({len(binned)} binned), {n} frames '
          f'expected ({(packets[-1][0] - packets[0][0]) * 1e-9:.2f} s, {pcfg.events_per_frame} '
          f'events per frame {pcfg.width}x{pcfg.height}, rectify {pcfg.rectify}, '
          f'{config.name})')
    return Plan(packets, t_frames, completing, pk_over, rs_over)


def replay(pub: Any, packets: list[tuple[int, bytes]]) -> np.ndarray:
    """Publish every packet at its bag time (1x, real time); the wall time of each publish."""
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
    return sent


def measure(p: Plan, logs: Path, config: Path) -> Outcome:
    """Start the two nodes, replay the packets, and collect arrivals and diagnostics."""
    frame_of = {int(t): k for k, t in enumerate(p.t_frames)}
    received = np.full(p.n, np.nan)
    extra = 0

    def on_odom(msg: Odometry) -> None:
        nonlocal extra
        now = time.perf_counter()
        k = frame_of.get(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
        if k is None:
            extra += 1
        else:
            received[k] = now

    os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
    rclpy.init()
    graph, mon = G.Graph(logs), G.Monitor()
    stop = threading.Event()
    try:
        graph.start_module('packetizer_node', 'packetizer_node', G.ros_args(
            config, {**p.packetizer, 'diagnostics_period_s': 0.25},
            {'~/events': G.EVENTS_TOPIC}))
        graph.start_module('resonator_node', 'resonator_node', G.ros_args(
            config, {**p.resonator, 'diagnostics_period_s': 0.25},
            {'~/frames': G.FRAMES_TOPIC}))
        sub_node = rclpy.create_node('latency_probe')
        sub_node.create_subscription(Odometry, G.ODOM_TOPIC, on_odom, qos(1000))
        pub = mon.node.create_publisher(EventPacket, G.EVENTS_TOPIC, qos(1000, reliable=False))
        mon.wait(lambda: pub.get_subscription_count() > 0
                 and mon.value('packetizer_node', 'frames_subscribers', 0) > 0
                 and mon.value('resonator_node', 'odom_subscribers', 0) > 0, 60,
                 'the graph', graph)
        ex = SingleThreadedExecutor()
        ex.add_node(sub_node)

        def spin() -> None:
            while not stop.is_set():
                ex.spin_once(timeout_sec=0.05)
        spinner = threading.Thread(target=spin)
        spinner.start()
        try:
            time.sleep(1.0)
            sent = replay(pub, p.packets)
            end = time.monotonic() + 10
            while np.isnan(received).any() and time.monotonic() < end:
                time.sleep(0.1)
            settle = time.monotonic() + 1.0   # let the last diagnostics arrive
            mon.wait(lambda: time.monotonic() > settle, 5, 'diagnostics')
        finally:
            stop.set()
            spinner.join()
        diags = dict(mon.diags)
        cpu = {nd.name: cpu_seconds(nd.proc.pid) for nd in graph.nodes}
    finally:
        graph.stop()
        mon.close()
        rclpy.try_shutdown()
    return Outcome(sent, received, extra, diags, cpu)


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def report(p: Plan, o: Outcome, seconds: float) -> bool:
    """Print drops, latency percentiles, processing and CPU times; whether targets are met."""
    n, got = p.n, ~np.isnan(o.received)
    pk, rs = o.diags.get('packetizer_node', {}), o.diags.get('resonator_node', {})
    print(f'frames expected {n}, made by the packetizer {pk.get("frames_out", "?")}, odometry '
          f'out {int(got.sum())}, dropped {n - int(got.sum())} (unmatched stamps {o.extra}); '
          f'bad messages packetizer {pk.get("bad_total", "?")}, '
          f'resonator {rs.get("bad_total", "?")}; the resonator took {rs.get("frames_in", "?")} '
          f'frames, its queue dropped {rs.get("seq_gaps", "?")}')
    if not got.any():
        print('no odometry received: no latency figures (node logs in --work/logs)')
        return False
    edges = np.flatnonzero(np.concatenate([[True], got, [True]]))
    runs = np.diff(edges) - 1
    at = int(edges[int(np.argmax(runs))])           # its first frame
    print(f'longest run of frames without odometry: {int(runs.max())} '
          f'({int((runs > 0).sum())} runs), from frame {at} '
          f'({(p.t_frames[min(at, n - 1)] - p.t_frames[0]) * 1e-9:.2f} s in)')
    lat_ms = (o.received[got] - o.sent[p.completing[got]]) * 1e3
    med, p99 = float(np.median(lat_ms)), float(np.percentile(lat_ms, 99))
    print(f'end-to-end latency (packet published -> odometry received): median {med:.2f} ms, '
          f'p90 {np.percentile(lat_ms, 90):.2f} ms, p99 {p99:.2f} ms, max {lat_ms.max():.2f} ms')
    print(f'resonator processing per frame: median {rs.get("processing_ms_median")} ms, p99 '
          f'{rs.get("processing_ms_p99")} ms (recent window); packetizer per packet: median '
          f'{pk.get("processing_ms_median")} ms')
    print('CPU time of the node processes (whole run, incl. start-up): ' + ', '.join(
        f'{k} {v:.2f} s = {v / max(n, 1) * 1e3:.2f} ms per frame' for k, v in o.cpu.items())
        + f'; frame period {seconds / max(n, 1) * 1e3:.2f} ms; load average '
        f'{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores')
    ok = n == int(got.sum()) and med <= 5.0 and p99 <= 20.0
    print(f'targets (no drop, median <= 5 ms, p99 <= 20 ms): {"met" if ok else "NOT met"}')
    return ok


def main() -> int:
    """Prepare, measure and report; exit 1 if no odometry came back at all."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--seconds', type=float, default=20.0, help='simulated sequence length')
    ap.add_argument('--seed', type=int, default=11, help='simulator seed')
    ap.add_argument('--dataset', type=Path, default=None,
                    help='an Event Camera Dataset folder with calib.txt (default: simulate)')
    ap.add_argument('--work', type=Path, default=Path('/tmp/hrn_bench_latency'))
    ap.add_argument('--config', type=Path, default=CONFIG,
                    help='params file of both nodes (default config/shapes_rotation.yaml; '
                    'config/live.yaml for a sensor of any size)')
    ap.add_argument('--rset', action='append', default=[], metavar='KEY=VALUE',
                    help='a resonator_node parameter (repeatable), e.g. frames_depth=10: a '
                    'shallow frame queue bounds the latency when the resonator falls behind')
    ap.add_argument('--smoke', action='store_true',
                    help=f'a {SMOKE_SECONDS:g} s sequence: only that it runs')
    args = ap.parse_args()
    if args.smoke:
        args.seconds = min(args.seconds, SMOKE_SECONDS)
    seq, bag = prepare(args.work, args.seconds, args.seed, args.dataset)
    p = plan(seq, bag, args.config)
    packetizer, resonator = parse_overrides(args.rset)     # values parsed as hrn-vo run --set
    if packetizer:          # the expected frames are planned with the packetizer config above
        ap.error(f'--rset sets resonator_node parameters, not {", ".join(packetizer)}')
    p.resonator.update(resonator)
    if args.rset:
        print(f'resonator_node parameters: {" ".join(args.rset)}')
    o = measure(p, args.work / 'logs', args.config)
    seconds = (p.packets[-1][0] - p.packets[0][0]) * 1e-9
    report(p, o, seconds)
    return 0 if (~np.isnan(o.received)).any() else 1


if __name__ == '__main__':
    sys.exit(main())
