"""Soak: the demo bag looped through the node graph at 1x for minutes (memory, drops, accuracy).

Simulates a rotation sequence (``--seconds``, default 20 s as ``hrn-vo demo``; cached in
``--work``), converts it to a bag, starts ``packetizer_node`` and ``resonator_node`` as real
processes with ``config/shapes_rotation.yaml`` and the parameters ``hrn-vo run`` derives from the
dataset (``calib.*`` included, the config rectifies), and replays the bag's event packets in a
loop at 1x (RELIABLE, as ``bag_player`` with ``reliable``) for ``--minutes`` (default 10). Each
loop starts the sensor clock again, as a looped bag does: the nodes see a clock reset per loop.
A subscriber in this process collects every readout (``~/readout``); a new loop is where the
stamps go back.

Prints the resident memory (VmRSS) of each node every ``--sample-s`` seconds and its start,
maximum, end and growth; frames expected, made and estimated per loop (dropped = expected -
estimated); and per loop the evaluation protocol's metrics against the ground truth
(core/evaluation) and the RMS difference of the readouts from the first loop's at the same
frame times. Not part of CI; ``--smoke`` (two 2.5 s loops) runs in the test suite.

    scripts/run.sh python bench/bench_soak.py                    # 10 min, 20 s loops, seed 11
    scripts/run.sh python bench/bench_soak.py --minutes 4 --work /tmp/soak
    scripts/run.sh python bench/bench_soak.py --smoke --work /tmp/soak1   # only that it runs
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import os
from pathlib import Path
import sys
import threading
import time

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from event_camera_msgs.msg import EventPacket  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from hrn_vo_ros.core.evaluation.protocol import evaluate  # noqa: E402
from hrn_vo_ros.core.evaluation.series import EstimateSeries  # noqa: E402
from hrn_vo_ros.core.events.frames import with_calibration  # noqa: E402
from hrn_vo_ros.errors import HrnVoError  # noqa: E402
from hrn_vo_ros.io import bags  # noqa: E402
from hrn_vo_ros.io.ecd import read_calib, read_events, read_groundtruth  # noqa: E402
from hrn_vo_ros.io.yamlconfig import dataset_configs  # noqa: E402
from hrn_vo_ros.nodes import graph as G  # noqa: E402,N812
from hrn_vo_ros.nodes.common import qos  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_latency  # noqa: E402

CONFIG = ROOT / 'config' / 'shapes_rotation.yaml'
NODES = ('packetizer_node', 'resonator_node')


def prepare(work: Path, seconds: float, seed: int) -> tuple[Path, Path]:
    """The simulated sequence and its bag, re-used when present (as bench_latency makes them)."""
    return bench_latency.prepare(work, seconds, seed, None)


def load_packets(bag: Path) -> list[tuple[int, bytes]]:
    """(bag time, CDR bytes) of every event packet."""
    with bags.open_bag(bag) as reader:
        return [(m.t_ns, bytes(m.raw)) for m in bags.iter_messages(reader, [G.EVENTS_TOPIC])]


def node_params(seq: Path) -> tuple[dict[str, list[str]], int]:
    """The node arguments (as ``run_graph`` wires them, plus ``calib.*``), events per frame."""
    pk_over, rs_over = G.dataset_overrides(seq, CONFIG, imu=False)
    pcfg = dataset_configs(CONFIG, seq, resonator={'imu.enabled': False}).packetizer
    if pcfg.rectify != 'none':
        c = with_calibration(pcfg, read_calib(seq)).calib
        pk_over = {**pk_over, 'calib.fx': c.fx, 'calib.fy': c.fy, 'calib.cx': c.cx,
                   'calib.cy': c.cy, 'calib.dist': [float(d) for d in c.dist]}
    args = G.graph_ros_args(CONFIG, imu=False, overrides=rs_over)
    args['packetizer_node'] += G.ros_args(None, pk_over)[1:]
    return args, pcfg.events_per_frame


@dataclass
class Sink:
    """Readouts (split into loops where the stamps go back) and the nodes' diagnostics."""

    node: Node
    loops: list[list[tuple[int, float, float, float]]] = field(default_factory=list)
    diags: dict[str, dict[str, str]] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def __post_init__(self) -> None:
        self.node.create_subscription(JointState, G.READOUT_TOPIC, self._on_readout,
                                      qos(G.FRAMES_DEPTH))
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 100)

    def readout_matched(self) -> bool:
        """Whether the readout subscription has matched the resonator's publisher."""
        return bool(self.node.get_publishers_info_by_topic(G.READOUT_TOPIC))

    def _on_readout(self, msg: JointState) -> None:
        t = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        h, v, r = (float(x) for x in msg.position[:3])
        with self.lock:
            if not self.loops or t < self.loops[-1][-1][0]:
                self.loops.append([])
            self.loops[-1].append((t, h, v, r))

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            self.diags[st.name.split(':')[0]] = {kv.key: kv.value for kv in st.values}

    def count(self) -> int:
        """Readouts received so far."""
        with self.lock:
            return sum(len(loop) for loop in self.loops)

    def value(self, node: str, key: str) -> int:
        """An integer counter of a node's latest diagnostics (0 when absent)."""
        try:
            return int(self.diags.get(node, {}).get(key, 0))
        except ValueError:
            return 0


def rss_mb(pid: int) -> float:
    """Resident memory of a process, MB (nan once it is gone)."""
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float('nan')


@dataclass
class Samples:
    """RSS of each node over time."""

    pids: dict[str, int]
    t0: float = field(default_factory=time.monotonic)
    rows: list[tuple[float, dict[str, float]]] = field(default_factory=list)

    def take(self, loops_done: int, readouts: int) -> None:
        """One sample, printed as a line of the RSS table."""
        row = {n: rss_mb(p) for n, p in self.pids.items()}
        t = time.monotonic() - self.t0
        self.rows.append((t, row))
        print(f'  {t:7.0f} s  loop {loops_done:3d}  readouts {readouts:7d}  '
              + '  '.join(f'{n} {row[n]:7.1f}' for n in self.pids), flush=True)


def replay_loop(pub: object, packets: list[tuple[int, bytes]], samples: Samples,
                sample_s: float, loop: int, sink: Sink) -> None:
    """One pass over the packets at 1x (real time), sampling RSS on the way."""
    t_bag0, t_wall0 = packets[0][0], time.perf_counter() + 0.05
    next_sample = samples.t0 + sample_s * (len(samples.rows))
    for t_bag, raw in packets:
        due = t_wall0 + (t_bag - t_bag0) * 1e-9
        while (lag := due - time.perf_counter()) > 0:
            time.sleep(min(lag, 0.002))
        pub.publish(raw)  # type: ignore[attr-defined]
        if time.monotonic() >= next_sample:
            samples.take(loop, sink.count())
            next_sample += sample_s


def per_loop_report(sink: Sink, gt_path: Path, expected: int) -> None:
    """Frames per loop, evaluation metrics and the difference from the first loop."""
    gt = read_groundtruth(gt_path)
    with sink.lock:
        loops = [np.asarray(loop, dtype=np.float64) for loop in sink.loops]
    first: dict[int, np.ndarray] = {}
    print(f'per-loop accuracy ({expected} frames expected per loop):')
    for k, arr in enumerate(loops, 1):
        t = arr[:, 0].astype(np.int64)
        n = len(t)
        est = EstimateSeries(t=t, h=arr[:, 1], v=arr[:, 2], r=arr[:, 3])
        try:
            res = evaluate(gt, est, 'rotation')
            metrics = '  '.join(f'{m} {v:.4g}' for m, v in sorted(res.metrics.items()))
        except HrnVoError as err:
            metrics = f'not evaluated ({err})'
        if k == 1:
            first = {int(tt): row for tt, row in zip(t, arr[:, 1:], strict=True)}
            diff = 'reference'
        else:
            common = [(first[int(tt)], row) for tt, row in zip(t, arr[:, 1:], strict=True)
                      if int(tt) in first]
            if common:
                a = np.asarray([c[0] for c in common])
                b = np.asarray([c[1] for c in common])
                rms = np.sqrt(np.mean((a - b) ** 2, axis=0))
                diff = (f'vs loop 1 on {len(common)} frames: RMS h {rms[0]:.3g} v {rms[1]:.3g} '
                        f'r {rms[2]:.3g}')
            else:
                diff = 'no frame time in common with loop 1'
        print(f'  loop {k:3d}: {n:5d} estimates ({expected - n:+d} dropped)  {metrics}  {diff}')


def main(argv: list[str] | None = None) -> int:
    """Run the soak and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--minutes', type=float, default=10.0, help='soak duration (whole loops)')
    ap.add_argument('--seconds', type=float, default=20.0, help='simulated sequence length')
    ap.add_argument('--seed', type=int, default=11)
    ap.add_argument('--sample-s', type=float, default=15.0, help='RSS sampling period')
    ap.add_argument('--work', type=Path, default=Path('/tmp/hrn_bench_soak'))
    ap.add_argument('--smoke', action='store_true', help='two 2.5 s loops (only that it runs)')
    args = ap.parse_args(argv)
    if args.smoke:
        args.seconds, args.minutes, args.sample_s = 2.5, 0.0, 1.0
    args.work.mkdir(parents=True, exist_ok=True)
    seq, bag = prepare(args.work, args.seconds, args.seed)
    packets = load_packets(bag)
    node_args, per_frame = node_params(seq)
    expected = len(read_events(seq)) // per_frame
    loops = max(2, int(np.ceil(args.minutes * 60 / args.seconds)))
    print(f'soak: {loops} loops of {args.seconds:g} s ({len(packets)} packets, {expected} '
          f'frames each) at 1x; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs')
    rclpy.init()
    graph = G.Graph(args.work / 'logs')
    node = Node('soak_source')
    sink = Sink(node)
    pub = node.create_publisher(EventPacket, G.EVENTS_TOPIC, qos(1000))
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    t_start = time.monotonic()
    codes: dict[str, int] = {}
    try:
        for name in reversed(NODES):
            graph.start_module(name, name, node_args[name])
        end = time.monotonic() + 120.0
        while not (pub.get_subscription_count() > 0
                   and sink.value('packetizer_node', 'frames_subscribers') > 0
                   and node.count_publishers(G.READOUT_TOPIC) > 0
                   and sink.readout_matched()):
            graph.check_alive()
            if time.monotonic() > end:
                raise G.GraphError(f'the nodes did not connect; diagnostics {sink.diags}')
            time.sleep(0.1)
        samples = Samples({n.name: n.proc.pid for n in graph.nodes})
        print('RSS (MB) over time:')
        samples.take(0, 0)
        for k in range(loops):
            replay_loop(pub, packets, samples, args.sample_s, k + 1, sink)
            graph.check_alive()
            time.sleep(0.3)  # a pause between loops, as a bag restarting
        want = loops * expected
        end = time.monotonic() + 120.0
        last, since = -1, time.monotonic()
        while sink.count() < want and time.monotonic() < end:   # drain, or stop moving
            if sink.count() != last:
                last, since = sink.count(), time.monotonic()
            elif time.monotonic() - since > 10.0:
                break
            time.sleep(0.2)
        time.sleep(1.0)  # a last diagnostics period
        samples.take(loops, sink.count())
        wall = time.monotonic() - t_start
        diags = {n: dict(sink.diags.get(n, {})) for n in NODES}
    finally:
        codes = graph.stop(timeout=20.0)
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    print('RSS summary (MB):')
    for name in samples.pids:
        vals = np.array([row[name] for _, row in samples.rows])
        start, peak, last_v = vals[0], np.nanmax(vals), vals[-1]
        print(f'  {name:16s} start {start:7.1f}  max {peak:7.1f}  end {last_v:7.1f}  growth '
              f'{100 * (last_v - start) / start:+6.1f} %')
    pk, rs = diags['packetizer_node'], diags['resonator_node']
    got = sink.count()
    print(f'frames: {loops} x {expected} = {loops * expected} expected, packetizer made '
          f'{pk.get("frames_out")}, resonator got {rs.get("frames_in")}, {got} estimates '
          f'received ({loops * expected - got} dropped); packets in {pk.get("packets_in")} of '
          f'{loops * len(packets)} (seq gaps {pk.get("seq_gaps")}), rejected: packetizer '
          f'{pk.get("bad_total")}, resonator {rs.get("bad_total")}; clock resets: packetizer '
          f'{pk.get("clock_resets")}, resonator {rs.get("clock_resets")}')
    per_loop_report(sink, seq, expected)
    print(f'exit codes {codes}; load average {os.getloadavg()[0]:.2f}; wall {wall:.0f} s')
    bad = {n: c for n, c in codes.items() if c != 0}
    print('soak done' + (f' (nodes exited with {bad})' if bad else ''))
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
