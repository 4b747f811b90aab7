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
from hrn_vo_ros.io import ros_msgs

EVENTS_TOPIC = '/event_camera/events'
IMU_TOPIC = '/imu'
FRAMES_TOPIC = '/packetizer_node/frames'
READOUT_TOPIC = '/resonator_node/readout'
ODOM_TOPIC = '/resonator_node/odom'
POSE_TOPIC = '/resonator_node/pose'
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
                   events_topic: str = EVENTS_TOPIC, imu_topic: str = IMU_TOPIC
                   ) -> dict[str, list[str]]:
    """The arguments of packetizer and resonator, wired as the launch file wires them."""
    pk = ros_args(params_file, {'events_reliable': True},
                  {'~/events': events_topic})
    rs_params = {'imu.enabled': imu, **overrides}
    rs = ros_args(params_file, rs_params, {'~/frames': FRAMES_TOPIC, '~/imu': imu_topic})
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
        log = self.log_dir / f'{name}.log'
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
                tail = n.log.read_text(errors='replace')[-2000:]
                raise GraphError(f'{n.name} exited with code {code}; log {n.log}:\n{tail}')

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


def diag_status(msg: DiagnosticArray) -> dict[str, str]:
    """Key/values of a diagnostics message (re-exported for tools)."""
    return ros_msgs.diagnostic_values(msg)


def init_ros() -> None:
    """``rclpy.init`` unless already initialised (the monitor needs a context)."""
    if not rclpy.ok():
        rclpy.init()
