"""Helpers shared by the package's nodes: QoS profiles, throttled rejects, the Jazzy main()."""

from __future__ import annotations

from collections.abc import Callable
import time
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.nodes.stats import NodeStats


def qos(depth: int, *, reliable: bool = True, keep_all: bool = False) -> QoSProfile:
    """KEEP_LAST ``depth`` (or KEEP_ALL), VOLATILE, RELIABLE or BEST_EFFORT."""
    return QoSProfile(history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
                      depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


class Rejects:
    """Counts malformed messages by kind and logs each kind at most once per throttle period.

    Each kind logs through its own child logger, so one noisy kind cannot hide another.
    """

    def __init__(self, node: Node, stats: NodeStats, throttle_s: Callable[[], float]) -> None:
        self._node = node
        self._stats = stats
        self._throttle_s = throttle_s
        self._loggers: dict[str, Any] = {}

    def __call__(self, kind: str, detail: object) -> None:
        """Count one rejected message of ``kind`` and log why (throttled)."""
        self._stats.reject(kind)
        logger = self._loggers.get(kind)
        if logger is None:
            logger = self._loggers[kind] = self._node.get_logger().get_child(kind)
        logger.warning(f'dropped a message ({kind}, {self._stats.bad[kind]} so far): {detail}',
                       throttle_duration_sec=self._throttle_s())


def publish_diagnostics(node: Node, pub: Any, stats: NodeStats, extra: list[tuple[str, object]],
                        *, level: str = 'ok', message: str = 'running') -> None:
    """Publish the node's counters (plus ``extra``) as one DiagnosticStatus."""
    t_ns = time.time_ns()
    name = f'{node.get_name()}: {node.get_fully_qualified_name()}'
    if stats.bad and level == 'ok':
        level, message = 'warn', f'{sum(stats.bad.values())} malformed messages dropped'
    msg = ros_msgs.diagnostics(t_ns, name, 'hrn_vo_ros', level, message,
                               extra + stats.values())
    pub.publish(msg)


def run(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """The Jazzy entry point: init, spin, shut down cleanly on Ctrl-C or external shutdown.

    A :class:`ConfigError` while the node starts (bad parameters) is logged and gives exit 2.
    """
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = make_node()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ConfigError as err:
        rclpy.logging.get_logger('hrn_vo_ros').error(f'invalid parameters: {err}')
        code = 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code
