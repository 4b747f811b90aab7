"""Soak: the demo bag looped through the node graph at 1x for minutes (memory, drops, accuracy).

Simulates a rotation sequence (``--seconds``, default 20 s as ``hrn-vo demo``; cached in
``--work``), converts it to a bag, starts ``packetizer_node`` and ``resonator_node`` as real
processes with ``config/shapes_rotation.yaml`` and the parameters ``hrn-vo run`` derives from the
dataset (``calib.*`` included, the config rectifies), and replays the bag's event packets in a
loop at 1x (RELIABLE, as ``bag_player`` with ``reliable``) for ``--minutes`` (default 10). Each
loop starts the sensor clock again, as a looped bag does: the nodes see a clock reset per loop.
A subscriber in this process collects every readout (``~/readout``); a new loop is where the
stamps go back.

Prints the resident memory (VmRSS) of each node every ``--sample-s`` seconds and at the end of
every loop, with the frames the resonator is behind the packetizer (the frames queued in DDS
between them, from the diagnostics; now and the most so far) and the event packets the
packetizer is behind this player. The summary gives each node's RSS at the start, after the
warm-up (the end of ``--warmup-loops`` loops, default 1) and at the end, the growth from both,
and the largest sample. The DDS queues keep the buffers of their deepest backlog, so RSS steps
up when a backlog reaches a new maximum (docs/reliability.md, "Soak"). Then the frames
expected, made and estimated (dropped = expected - estimated); and per loop the evaluation
protocol's metrics against the ground truth (core/evaluation) and the RMS difference of the
readouts from the single pass: the same sequence run once through the same pipeline offline
(``hrn-vo run``'s path, seed 0 as the node), before the graph starts. Not part of CI;
``--smoke`` (two 2.5 s loops) runs in the test suite.

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

from hrn_vo_ros.cli import graph as G  # noqa: E402,N812
from hrn_vo_ros.core.evaluation.protocol import evaluate  # noqa: E402
from hrn_vo_ros.core.evaluation.series import EstimateSeries  # noqa: E402
from hrn_vo_ros.core.events.packet_config import with_calibration  # noqa: E402
from hrn_vo_ros.core.hrn.backends import BackendConfig  # noqa: E402
from hrn_vo_ros.core.live import make_resonator  # noqa: E402
from hrn_vo_ros.errors import HrnVoError  # noqa: E402
from hrn_vo_ros.io import bags  # noqa: E402
from hrn_vo_ros.io.ecd import read_calib, read_events, read_groundtruth  # noqa: E402
from hrn_vo_ros.io.pipeline import dataset_pipeline, run_dataset  # noqa: E402
from hrn_vo_ros.io.yamlconfig import dataset_configs  # noqa: E402
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


def single_pass(seq: Path) -> EstimateSeries:
    """The sequence run once offline through the node's resonator (``hrn-vo run``'s path)."""
    dc = dataset_configs(CONFIG, seq, resonator={'imu.enabled': False})
    pipe = dataset_pipeline(seq, dc.packetizer, lambda: make_resonator(
        dc.resonator, 0, BackendConfig())[0], with_z=dc.resonator.scale.enabled)
    return run_dataset(seq, pipe).series


@dataclass
class Sink:
    """Readouts (split into loops where the stamps go back) and the nodes' diagnostics."""

    node: Node
    loops: list[list[tuple[int, float, float, float]]] = field(default_factory=list)
    diags: dict[str, dict[str, str]] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)
    peak_behind: int = 0     # most frames the resonator was behind the packetizer so far

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
        self.peak_behind = max(self.peak_behind, self.behind())

    def behind(self) -> int:
        """Frames the resonator is behind the packetizer (the last diagnostics of each): the
        frames queued in DDS between them."""
        return (self.value('packetizer_node', 'frames_out')
                - self.value('resonator_node', 'frames_in'))

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
    """RSS of each node over time (periodic rows and one at the end of every loop)."""

    pids: dict[str, int]
    sink: Sink
    sample_s: float
    t0: float = field(default_factory=time.monotonic)
    rows: list[tuple[float, dict[str, float]]] = field(default_factory=list)
    loop_rows: dict[int, int] = field(default_factory=dict)   # loops done -> row index
    next_due: float = 0.0
    published: int = 0       # event packets sent so far

    def take(self, loops_done: int, *, loop_end: bool = False) -> None:
        """One sample, printed as a line of the RSS table."""
        row = {n: rss_mb(p) for n, p in self.pids.items()}
        t = time.monotonic() - self.t0
        self.rows.append((t, row))
        if loop_end:
            self.loop_rows[loops_done] = len(self.rows) - 1
        print(f'  {t:7.0f} s  loop {loops_done:3d}{" end" if loop_end else "    "}  readouts '
              f'{self.sink.count():7d}  behind {self.sink.behind():5d} (max '
              f'{self.sink.peak_behind:5d}) frames, '
              f'{self.published - self.sink.value("packetizer_node", "packets_in"):5d} packets  '
              + '  '.join(f'{n} {row[n]:7.1f}' for n in self.pids), flush=True)

    def due(self, loops_done: int) -> None:
        """A periodic sample when one is due."""
        now = time.monotonic()
        if now >= self.next_due:
            self.take(loops_done)
            nxt = self.next_due + self.sample_s
            self.next_due = nxt if nxt > now else now + self.sample_s

    def summary(self, warmup_loops: int) -> list[tuple[str, float, float]]:
        """Print start / warm-up / max / end per node; (name, growth from start, from warm-up)."""
        out = []
        warm = self.loop_rows.get(warmup_loops)
        print(f'RSS summary (MB), warm-up = the end of loop {warmup_loops}:')
        for name in self.pids:
            vals = np.array([row[name] for _, row in self.rows])
            start, peak, last_v = vals[0], np.nanmax(vals), vals[-1]
            w = vals[warm] if warm is not None else float('nan')
            g0, gw = 100 * (last_v - start) / start, 100 * (last_v - w) / w
            print(f'  {name:16s} start {start:7.1f}  warm-up {w:7.1f}  max {peak:7.1f}  end '
                  f'{last_v:7.1f}  growth from start {g0:+6.1f} %  from warm-up {gw:+6.1f} %')
            out.append((name, g0, gw))
        ends = sorted(self.loop_rows.items())
        if ends:
            print('  RSS at the end of each loop: ' + '; '.join(
                f'{k}: ' + ' '.join(f'{self.rows[i][1][n]:.1f}' for n in self.pids)
                for k, i in ends))
        return out


def replay_loop(pub: object, packets: list[tuple[int, bytes]], samples: Samples,
                loops_done: int) -> None:
    """One pass over the packets at 1x (real time), sampling RSS on the way."""
    t_bag0, t_wall0 = packets[0][0], time.perf_counter() + 0.05
    for t_bag, raw in packets:
        due = t_wall0 + (t_bag - t_bag0) * 1e-9
        while (lag := due - time.perf_counter()) > 0:
            time.sleep(min(lag, 0.002))
        pub.publish(raw)  # type: ignore[attr-defined]
        samples.published += 1
        samples.due(loops_done)


def _metrics(gt: object, est: EstimateSeries) -> dict[str, float] | str:
    try:
        return dict(evaluate(gt, est, 'rotation').metrics)  # type: ignore[arg-type]
    except HrnVoError as err:
        return f'not evaluated ({err})'


def per_loop_report(sink: Sink, gt_path: Path, expected: int, single: EstimateSeries) -> float:
    """Frames per loop, evaluation metrics and the difference from the single pass; returns
    the largest relative difference of a loop's mean angle error from the single pass's."""
    gt = read_groundtruth(gt_path)
    with sink.lock:
        loops = [np.asarray(loop, dtype=np.float64) for loop in sink.loops]
    ref = _metrics(gt, single)
    ref_rows = {int(t): np.array([h, v, r]) for t, h, v, r in zip(
        single.t, single.h, single.v, single.r, strict=True)}
    text = ('  '.join(f'{m} {v:.4g}' for m, v in sorted(ref.items()))
            if isinstance(ref, dict) else ref)
    print(f'single pass (offline, {len(single)} frames): {text}')
    print(f'per-loop accuracy ({expected} frames expected per loop):')
    worst = 0.0
    for k, arr in enumerate(loops, 1):
        t = arr[:, 0].astype(np.int64)
        n = len(t)
        res = _metrics(gt, EstimateSeries(t=t, h=arr[:, 1], v=arr[:, 2], r=arr[:, 3]))
        if isinstance(res, dict):
            metrics = '  '.join(f'{m} {v:.4g}' for m, v in sorted(res.items()))
            if isinstance(ref, dict) and 'mean_angle_deg' in ref:
                rel = res['mean_angle_deg'] / ref['mean_angle_deg'] - 1
                worst = max(worst, abs(rel))
                metrics += f'  (mean angle {100 * rel:+.1f} % vs single pass)'
        else:
            metrics, worst = res, float('inf')
        common = [(ref_rows[int(tt)], row) for tt, row in zip(t, arr[:, 1:], strict=True)
                  if int(tt) in ref_rows]
        if common:
            a = np.asarray([c[0] for c in common])
            b = np.asarray([c[1] for c in common])
            rms = np.sqrt(np.mean((a - b) ** 2, axis=0))
            diff = (f'vs single pass on {len(common)} frames: RMS h {rms[0]:.3g} v {rms[1]:.3g} '
                    f'r {rms[2]:.3g}')
        else:
            diff = 'no frame time in common with the single pass'
        print(f'  loop {k:3d}: {n:5d} estimates ({expected - n:+d} dropped)  {metrics}  {diff}')
    return worst


def main(argv: list[str] | None = None) -> int:
    """Run the soak and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--minutes', type=float, default=10.0, help='soak duration (whole loops)')
    ap.add_argument('--seconds', type=float, default=20.0, help='simulated sequence length')
    ap.add_argument('--seed', type=int, default=11)
    ap.add_argument('--sample-s', type=float, default=15.0, help='RSS sampling period')
    ap.add_argument('--warmup-loops', type=int, default=1,
                    help='RSS growth is also given from the end of this many loops')
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
    t_single = time.perf_counter()
    single = single_pass(seq)
    print(f'single pass offline: {len(single)} frames in {time.perf_counter() - t_single:.1f} s')
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
        samples = Samples({n.name: n.proc.pid for n in graph.nodes}, sink, args.sample_s)
        print('RSS (MB) over time:')
        samples.due(0)
        for k in range(loops):
            replay_loop(pub, packets, samples, k)
            graph.check_alive()
            time.sleep(0.3)  # a pause between loops, as a bag restarting
            samples.take(k + 1, loop_end=True)
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
        samples.take(loops)
        wall = time.monotonic() - t_start
        diags = {n: dict(sink.diags.get(n, {})) for n in NODES}
    finally:
        codes = graph.stop(timeout=20.0)
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    growth = samples.summary(args.warmup_loops)
    pk, rs = diags['packetizer_node'], diags['resonator_node']
    got = sink.count()
    print(f'frames: {loops} x {expected} = {loops * expected} expected, packetizer made '
          f'{pk.get("frames_out")}, resonator got {rs.get("frames_in")}, {got} estimates '
          f'received ({loops * expected - got} dropped); packets in {pk.get("packets_in")} of '
          f'{loops * len(packets)} (seq gaps {pk.get("seq_gaps")}), rejected: packetizer '
          f'{pk.get("bad_total")}, resonator {rs.get("bad_total")}; clock resets: packetizer '
          f'{pk.get("clock_resets")}, resonator {rs.get("clock_resets")}')
    worst = per_loop_report(sink, seq, expected, single)
    dropped = loops * expected - got
    print('targets: RSS growth under 5 % '
          + ', '.join(f'{n} {g0:+.1f} % from start / {gw:+.1f} % from warm-up'
                      for n, g0, gw in growth)
          + f'; frames dropped {dropped}; largest mean-angle difference of a loop from the '
          f'single pass {100 * worst:.1f} %')
    print(f'exit codes {codes}; load average {os.getloadavg()[0]:.2f} (1 min), '
          f'{os.getloadavg()[2]:.2f} (15 min); wall {wall:.0f} s')
    bad = {n: c for n, c in codes.items() if c != 0}
    print('soak done' + (f' (nodes exited with {bad})' if bad else ''))
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
