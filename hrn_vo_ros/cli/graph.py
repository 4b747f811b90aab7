"""Start the node graph as real processes and watch it (for ``hrn-vo demo``, tests, benchmarks).

A machine without ``launch`` still runs the same graph as ``launch/hrn_vo.launch.py``: each node
is its own process (``python -m hrn_vo_ros.nodes.<module> --ros-args ...``), logs go to files,
and a small monitor node in the calling process reads ``/diagnostics`` to know when the graph is
connected and when every frame has come out the other end. Processes are stopped with SIGINT
(the nodes' clean shutdown: the recorder finishes its bag) and killed only after a timeout.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from hrn_vo_ros.errors import HrnVoError

EVENTS_TOPIC = '/event_camera/events'
CAMERA_INFO_TOPIC = '/event_camera/camera_info'
IMU_TOPIC = '/imu'
FRAMES_TOPIC = '/packetizer_node/frames'
READOUT_TOPIC = '/resonator_node/readout'
ODOM_TOPIC = '/resonator_node/odom'
POSE_TOPIC = '/resonator_node/pose'
FRAMES_DEPTH = 10000
RECORDED = {
    READOUT_TOPIC: 'sensor_msgs/msg/JointState',
    ODOM_TOPIC: 'nav_msgs/msg/Odometry',
    POSE_TOPIC: 'geometry_msgs/msg/PoseStamped',
}


class GraphError(HrnVoError):
    """A node process of the graph failed or the graph did not finish in time."""


@dataclass
class NodeProcess:
    """One running node: its name, process and log file."""

    name: str
    proc: subprocess.Popen[bytes]
    log: Path

    def tail(self, chars: int = 2000) -> str:
        """The end of its log."""
        return _tail(self.log, chars)


def _tail(log: Path, chars: int) -> str:
    """The last ``chars`` characters of a node's log."""
    return log.read_text(errors='replace')[-chars:]


def ros_args(params_file: Path | None = None, params: dict[str, object] | None = None,
             remaps: dict[str, str] | None = None) -> list[str]:
    """``--ros-args`` for a node: a parameter file, ``-p`` overrides and ``-r`` remaps."""
    out = ['--ros-args']
    if params_file is not None:
        out += ['--params-file', str(params_file)]
    for key, value in (params or {}).items():
        text = str(value).lower() if isinstance(value, bool) else (
            '[' + ', '.join(repr(v) for v in value) + ']' if isinstance(value, list | tuple)
            else str(value))
        out += ['-p', f'{key}:={text}']
    for src, dst in (remaps or {}).items():
        out += ['-r', f'{src}:={dst}']
    return out


def graph_ros_args(params_file: Path | None, *, imu: bool, overrides: dict[str, object],
                   events_topic: str = EVENTS_TOPIC, imu_topic: str = IMU_TOPIC,
                   paced: bool = False) -> dict[str, list[str]]:
    """The arguments of packetizer and resonator, wired as the launch file wires them."""
    # A deep frame queue (~70 MB at most) absorbs the resonator falling behind for a while on a
    # loaded machine, so replay loses no frame; live use keeps the node default.
    pk = ros_args(params_file, {'events_reliable': True, 'diagnostics_period_s': 0.25,
                                'frames_depth': FRAMES_DEPTH, 'events_keep_all': paced,
                                'imu.enabled': imu},       # the packets of a fused gyro
                  {'~/events': events_topic, '~/camera_info': CAMERA_INFO_TOPIC})
    rs_params = {'imu.enabled': imu, 'diagnostics_period_s': 0.25, 'frames_depth': FRAMES_DEPTH,
                 'max_pending_frames': FRAMES_DEPTH, 'imu_depth': 50 * FRAMES_DEPTH, **overrides}
    rs = ros_args(params_file, rs_params, {'~/frames': FRAMES_TOPIC, '~/imu': imu_topic,
                                           '~/camera_info': CAMERA_INFO_TOPIC})
    return {'packetizer_node': pk, 'resonator_node': rs}


@dataclass
class Graph:
    """Node processes started by this process, stopped in reverse order.

    Args:
        log_dir: Where each process writes ``<name>.log``.
        python: Interpreter of the nodes (default: this one).
    """

    log_dir: Path
    python: str = sys.executable
    nodes: list[NodeProcess] = field(default_factory=list)

    def start(self, name: str, argv: Sequence[str]) -> NodeProcess:
        """Start ``argv`` (a module's ``-m`` path or an executable and its args)."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log = self.log_path(name)
        with open(log, 'wb') as fh:
            proc = subprocess.Popen(list(argv), stdout=fh, stderr=subprocess.STDOUT,
                                    env=os.environ.copy())
        node = NodeProcess(name, proc, log)
        self.nodes.append(node)
        return node

    def start_module(self, name: str, module: str, args: Sequence[str]) -> NodeProcess:
        """Start ``python -m hrn_vo_ros.nodes.<module> ARGS``."""
        return self.start(name, [self.python, '-m', f'hrn_vo_ros.nodes.{module}', *args])

    def check_alive(self) -> None:
        """Raise GraphError naming a node process that exited, with the end of its log."""
        for n in self.nodes:
            code = n.proc.poll()
            if code is not None and code != 0:
                raise GraphError(f'{n.name} exited with code {code}; log {n.log}:\n{n.tail()}')

    def stop(self, timeout: float = 30.0) -> dict[str, int]:
        """SIGINT every running node (last started first), then wait; kill after ``timeout``."""
        codes: dict[str, int] = {}
        for n in reversed(self.nodes):
            if n.proc.poll() is None:
                n.proc.send_signal(signal.SIGINT)
            try:
                codes[n.name] = n.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                n.proc.kill()
                codes[n.name] = n.proc.wait()
        self.nodes.clear()
        return codes

    def failed_logs(self, codes: dict[str, int], chars: int = 3000) -> dict[str, str]:
        """The end of the log of every node whose exit code in ``codes`` is not 0."""
        return {n: _tail(self.log_path(n), chars) for n, c in codes.items() if c != 0}

    def log_path(self, name: str) -> Path:
        """Where the node started as ``name`` writes its output."""
        return self.log_dir / f'{name}.log'


class Monitor:
    """A node in this process that reads ``/diagnostics`` of the graph's nodes."""

    def __init__(self) -> None:
        self.node = Node('hrn_vo_graph_monitor')
        self.diags: dict[str, dict[str, str]] = {}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 100)
        self._ex = SingleThreadedExecutor()
        self._ex.add_node(self.node)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            self.diags[st.name.split(':')[0]] = {kv.key: kv.value for kv in st.values}

    def value(self, node: str, key: str, default: int = -1) -> int:
        """An integer counter from a node's latest diagnostics."""
        try:
            return int(self.diags.get(node, {}).get(key, default))
        except ValueError:
            return default

    def subscribers(self, topic: str) -> int:
        """Subscriptions on ``topic`` known to the graph."""
        return self.node.count_subscribers(topic)

    def wait(self, cond: Callable[[], bool], timeout: float, what: str,
             graph: Graph | None = None) -> None:
        """Spin until ``cond()``; GraphError naming ``what`` on timeout or a dead node."""
        end = time.monotonic() + timeout
        while not cond():
            if graph is not None:
                graph.check_alive()
            if time.monotonic() > end:
                raise GraphError(f'timed out after {timeout:.0f} s waiting for {what}; '
                                 f'diagnostics so far: {self.diags}')
            self._ex.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        """Destroy the monitor node."""
        self._ex.remove_node(self.node)
        self.node.destroy_node()


def init_ros() -> bool:
    """``rclpy.init`` unless already initialised; True if this call initialised it."""
    if rclpy.ok():
        return False
    rclpy.init()
    return True


@dataclass(frozen=True)
class GraphResult:
    """What went through the graph: packets in, frames made, estimates recorded, wall time."""

    packets: int
    packets_in: int
    frames: int
    estimates: int
    seconds: float
    diagnostics: dict[str, dict[str, str]]


def player_argv(python: str, bag: Path, rate: float, *, imu: bool = False) -> list[str]:
    """The bag player (``nodes/bag_player.py``): RELIABLE, after the packetizer (and with
    ``imu`` the resonator's IMU subscription) subscribed.

    ``rate`` 0 plays at ``max_rate`` (KEEP_ALL writers paced by the subscribers).
    """
    params: dict[str, object] = {'bag': str(bag), 'reliable': True, 'wait_for_subscribers': 1}
    if imu:
        params['wait_topics'] = [EVENTS_TOPIC, IMU_TOPIC]
    params.update({'max_rate': True} if rate <= 0 else {'rate': float(rate)})
    return [python, '-m', 'hrn_vo_ros.nodes.bag_player', *ros_args(None, params)]


def dataset_overrides(dataset: Path | None, params_file: Path | None, *, imu: bool
                      ) -> tuple[dict[str, object], dict[str, object]]:
    """The parameters ``hrn-vo run`` derives from the dataset, so the graph computes the same.

    :func:`~hrn_vo_ros.io.yamlconfig.dataset_configs` (sensor size, frame size, the
    resonator's focal length where the IMU or the sphere correction need it; refuses the sphere
    correction on frames that are not equidistant) plus the odometry focal length, fx from
    ``calib.txt`` divided by the downsampling factor.

    Returns:
        ``(packetizer, resonator)`` parameter overrides.

    Raises:
        ConfigError, DatasetError: as ``dataset_configs``.
    """
    from hrn_vo_ros.io.ecd import read_calib
    from hrn_vo_ros.io.yamlconfig import dataset_configs

    rs: dict[str, object] = {'imu.enabled': imu}
    if dataset is None:
        return {}, rs
    dc = dataset_configs(params_file, dataset, packetizer={'imu.enabled': imu}, resonator=rs)
    focal = read_calib(dataset).fx / dc.packetizer.factor
    return dict(dc.packetizer_overrides), {**dc.resonator_overrides,
                                           'odometry.focal_length_px': focal}


def run_graph(bag: Path, out_bag: Path, log_dir: Path, *, params_file: Path | None,
              dataset: Path | None = None, imu: bool = False, rate: float = 1.0,
              timeout: float = 600.0, settle_s: float = 3.0) -> GraphResult:
    """Replay ``bag`` through packetizer → resonator, record the outputs into ``out_bag``.

    Raises:
        GraphError: if a node dies, the graph does not connect, or frames go missing.
    """
    from hrn_vo_ros.io.bags import open_bag

    reader = open_bag(bag)
    try:
        packets = sum(c.msgcount for c in reader.connections if c.topic == EVENTS_TOPIC)
    finally:
        reader.close()
    pk_over, rs_over = dataset_overrides(dataset, params_file, imu=imu)
    args = graph_ros_args(params_file, imu=imu, overrides=rs_over, paced=rate <= 0)
    args['packetizer_node'] += [a for k, v in pk_over.items() for a in ('-p', f'{k}:={v}')]
    topics = [f'{k}:{v}' for k, v in RECORDED.items()]
    owned = init_ros()
    graph, mon = Graph(log_dir), Monitor()
    t0 = time.monotonic()
    try:
        graph.start_module('bag_recorder', 'bag_recorder',
                           ros_args(None, {'output': str(out_bag), 'topics': topics,
                                                 'diagnostics_period_s': 0.25}))
        graph.start_module('resonator_node', 'resonator_node', args['resonator_node'])
        graph.start_module('packetizer_node', 'packetizer_node', args['packetizer_node'])
        # Writers must have matched their readers (not just be known to the graph), or the
        # first frames of a volatile topic are lost.
        mon.wait(lambda: mon.value('packetizer_node', 'frames_subscribers', 0) > 0
                 and mon.value('resonator_node', 'output_subscribers', 0) > 0,
                 60.0, 'the nodes to connect', graph)
        player = graph.start('bag_player', player_argv(graph.python, bag, rate, imu=imu))
        mon.wait(lambda: player.proc.poll() is not None, timeout, 'the bag player', graph)
        if player.proc.returncode != 0:
            raise GraphError(f'the bag player failed (exit {player.proc.returncode}); log '
                             f'{player.log}:\n{player.tail()}')
        graph.nodes.remove(player)
        done = _settled(mon, graph, packets, settle_s, timeout)
        diags = dict(mon.diags)
    finally:
        codes = graph.stop()
        mon.close()
        if owned:
            rclpy.try_shutdown()
    bad = {k: c for k, c in codes.items() if c not in (0, -2)}
    if bad:
        raise GraphError(f'node processes exited with {bad}; logs in {log_dir}')
    return GraphResult(packets, done[0], done[1], done[2], time.monotonic() - t0, diags)


def _settled(mon: Monitor, graph: Graph, packets: int, settle_s: float,
             timeout: float) -> tuple[int, int, int]:
    """Wait until every frame the packetizer made was recorded and nothing moves any more."""
    def counts() -> tuple[int, int, int]:
        return (mon.value('packetizer_node', 'packets_in'),
                mon.value('packetizer_node', 'frames_out'),
                mon.value('bag_recorder', 'recorded ' + READOUT_TOPIC, 0))
    last, since = counts(), time.monotonic()

    def stable() -> bool:
        nonlocal last, since
        now = counts()
        if now != last:
            last, since = now, time.monotonic()
        complete = now[0] == packets and now[2] >= now[1] >= 0
        return complete or (time.monotonic() - since > settle_s + 2.0 and now[1] >= 0)
    mon.wait(stable, timeout, 'the graph to drain', graph)
    if last[0] != packets or last[2] != last[1]:
        raise GraphError(f'frames went missing: {packets} packets in the bag, '
                         f'{last[0]} received by the packetizer, {last[1]} frames made, '
                         f'{last[2]} estimates recorded; diagnostics: {mon.diags}')
    return last
